"""From timer bytes to timed descents: line framing, the wire formats of ALGE, TAG Heuer and
Microgate timers, impulse records, the descent assembler, and hand-typed times files. Pure:
no I/O (the times-file reader excepted), no threads."""
