"""Raw chunks -> lines -> impulses -> descents -> fits -> result rows, with no I/O.

The same :class:`Processor` runs live (fed by the serial reader after each chunk is logged)
and in replay (fed from the raw log or a plain capture), so a replay reproduces the live
results exactly. Time-outs are the one thing that depends on the clock rather than on the
bytes. A live time-out is written to the raw log as a ``timeout`` event, and replay applies
it from there. Impulse-driven endings (the next start, the last photocell, an impulse after
the time-out) need no clock at all.
"""

from __future__ import annotations

import math
from array import array
from collections import Counter, deque
from collections.abc import Callable, Iterable

from station.errors import InputError
from station.session.config import StationConfig
from station.session.rawlog import Chunk, Lines
from station.session.records import LineCounts
from station.survey.track import Track
from station.timing.assembly import DescentAssembler, ImpulseEvent, TimedDescent
from station.timing.framing import LineFramer
from station.timing.impulses import MEMORY_REPEAT, Edit, Impulse, Parsed, Skip, Unparsed
from station.timing.wireformats import make_parser

#: unparsed lines listed (line, reason, first 100 characters): a day of line noise stays within
#: tens of MB; beyond it one entry says that more were not listed
MAX_UNPARSED = 100_000
#: the timer's own marks of a memory download on the line (TAG ``DS`` … ``DE``): between
#: them the impulses are from its memory (:attr:`DescentAssembler.from_memory`)
MEMORY_DOWNLOAD = {"memory download starts": True, "memory download ends": False}
#: the lines last handed to the assembler whose host times are kept: a start it holds (a time
#: far from its clock waits for the next impulse to confirm it) is at most a few lines back
#: (edits may come between); one further back is dated by the line that started it
RECENT_LINES = 16
#: a bulk replay of a session hands the assembler this many lines at most at once
SESSION_RUN = 4096


class StartHosts:
    """The host clock at each descent's start, by descent number (they count from 1), or
    None: 8 bytes a descent in an array, not a dict entry and a float (a day keeps them all:
    a refit after an annotation dates its descent again)."""

    def __init__(self) -> None:
        self._t = array("d")  # NaN: none known
        self._nan: set[int] = set()  # those whose host time was NaN itself

    def __setitem__(self, number: int, t: float | None) -> None:
        if number < 1:
            raise IndexError(number)
        gap = number - len(self._t)
        if gap > 0:
            self._t.extend([math.nan] * gap)
        self._t[number - 1] = math.nan if t is None else t
        if t is not None and t != t:
            self._nan.add(number)
        else:
            self._nan.discard(number)

    def get(self, number: int) -> float | None:
        if not 1 <= number <= len(self._t):
            return None
        t = self._t[number - 1]
        return t if t == t or number in self._nan else None


class Processor:
    """Bytes in, finished descents out; counts every kind of line on the way."""

    def __init__(self, config: StationConfig, track: Track) -> None:
        known = set(track.photocell_ids)
        for ch, pc in config.channels.items():
            if pc not in known:
                raise InputError(
                    f"photocell {pc!r} is not in the survey ({', '.join(track.photocell_ids)})",
                    path=config.path,
                    field=f"photocells.{ch}",
                )
        self.parser = make_parser(config.serial.protocol)
        self.framer = LineFramer()
        positions = [
            track.profile.arc_length(track.photocells[0].x, pc.x) for pc in track.photocells
        ]
        self.assembler = DescentAssembler(
            track.photocell_ids,
            config.channels,
            debounce_s=config.descent.debounce_s,
            timeout_s=config.descent.timeout_s,
            positions_m=positions,
            min_speed_ms=config.descent.min_speed_ms,
            pairing=config.descent.pairing,
        )
        self.lines = 0
        self.counts: Counter[str] = Counter()  # edits, skipped, unparsed, memory impulses
        self.impulses = 0  # counted apart: one per impulse line, the common case
        self.unparsed: list[tuple[int, str, str]] = []  # line number, reason, text (first 100)
        self.connection: list[tuple[float, str, str]] = []
        self.offset_us: int | None = None  # device clock − host clock, by live impulses kept
        #: the same while the timer's memory comes, by its impulses kept: their times are not
        #: the timer's now, but its descents end by them (a tick's "now" follows them, as a
        #: time far from the memory's clock is confirmed by them); None: none yet
        self.memory_offset_us: int | None = None
        #: the line of the TAG ``DS`` whose memory download is coming over the line (its
        #: ``DE`` not seen yet); None: none is
        self.download_line: int | None = None
        #: the lines before the latest ``import`` event (`station import`): that import's
        #: lines come after them (the descents it joined are those they went into)
        self.import_after_line: int | None = None
        self.start_host = StartHosts()
        self._latest_start: tuple[int, int] | None = None  # (device µs, descent): the last start
        #: (line, host time) of the lines last handed to the assembler: a descent's start may
        #: be a line before the one that made the assembler start it (a held start)
        self._recent: deque[tuple[int, float | None]] = deque(maxlen=RECENT_LINES)
        self._chunk_t: float | None = None  # host time of the latest bytes (the flushed line's)
        #: the resolution (µs) the timer states in its first impulse from a photocell (not a
        #: keypad's 1/100 s): the default of the timer's precision (station.model.timer); fixed
        #: from then on, so a live day and its replay judge every descent alike
        self.resolution_us: int | None = None
        self._photocell_channels = frozenset(config.channels)

    @property
    def events(self) -> list[ImpulseEvent]:
        return self.assembler.events

    def line_counts(self) -> LineCounts:
        """A snapshot of the counts, for the summary and the UI."""
        c = self.counts
        return LineCounts(
            self.lines, self.impulses, c["edit"], c["skipped"], c["unparsed"], c["memory"]
        )

    def _count_impulses(self, n: int) -> None:
        """``n`` impulse lines; those that came while the timer's memory comes (a TAG
        ``DS`` … ``DE``, an import) counted apart too: the summary says how many were the
        memory's."""
        self.impulses += n
        if self.assembler.from_memory:
            self.counts["memory"] += n

    def feed(self, chunk: Chunk) -> list[TimedDescent]:
        if chunk.event:
            if chunk.event == "timeout":
                return self.tick(chunk.t)
            if chunk.event != "session":
                self.connection.append((chunk.t, chunk.event, chunk.detail))
            if chunk.event == "import":
                self.import_after_line = self.lines
                self.download_line = None  # (the import's own DS sets it again)
                # a download of the timer's memory follows (`station import`): the times it
                # adds are earlier than the recording's last by nature; the timer's clock is
                # judged afresh from its first start (a reset within it is still flagged);
                # and an impulse of it may be the rest of a descent the recording has the
                # first crossings of (the cable came out during it): joined to it
                return self._memory_follows(chunk.t, fresh_clock=True)
            if chunk.event == "disconnected":
                self.assembler.disconnected(chunk.detail)
                self._memory_ends()  # a download on the line ends with it
            return []
        lines = self.framer.feed(chunk.data)
        t: float | None = chunk.t  # None: a plain capture (replay_chunks)
        self._chunk_t = t
        if len(lines) == 1:  # a live recording's every chunk
            line = lines[0]
            return self._parsed(line, self.parser.parse(line), t)
        if t is None:
            return self._capture_lines(lines)
        done: list[TimedDescent] = []
        for line in lines:
            ended = self._line(line, t)
            if ended:
                done += ended
        return done

    def _capture_lines(self, lines: list[str]) -> list[TimedDescent]:
        """:meth:`_line` for each line of a plain capture's chunk (no host clock), its runs of
        impulses in the assembler's batch: a replay of a capture is a hundred thousand of them."""
        done: list[TimedDescent] = []
        parsed_lines = self.parser.parse_lines(lines)  # (the parser's state is its own)
        asm = self.assembler
        feed, feed_run = asm.feed, asm.feed_run
        start_host, judge = self.start_host, self._started

        def undated(d: TimedDescent) -> None:  # no host clock: each start undated, judged
            start_host[d.number] = None
            judge(d)

        i, n = 0, len(lines)
        stopped = -1  # the impulse the batch stopped at: fed on its own
        while i < n:
            parsed = parsed_lines[i]
            # (while a download is on the line each impulse on its own: a live one ends it,
            # :meth:`_live_after_download`)
            if (
                type(parsed) is Impulse
                and self.resolution_us is not None
                and self.download_line is None
            ):
                if i != stopped:
                    stop, ended, _kept = feed_run(parsed_lines, i, self.lines + 1, undated)
                    if stop > i:
                        self.lines += stop - i
                        self._count_impulses(stop - i)
                        done += ended
                        i = stopped = stop
                        continue
                # one whose time the next impulse must confirm, on its own
                self.lines += 1
                self._count_impulses(1)
                before = asm.count
                ended = feed(parsed, self.lines, None)
                if asm.count > before:  # no host clock: each start undated, judged
                    self._new_descents(before, ended, None, judge=True)
            else:  # any other line, or the first impulse (it states the resolution)
                ended = self._parsed(lines[i], parsed, None)
            if ended:
                done += ended
            i += 1
        return done

    def feed_chunks(self, chunks: Iterable[Chunk | Lines]) -> list[TimedDescent]:
        """:meth:`feed` of each chunk in turn, for a bulk replay (``replay --no-fit``): the
        descents they finished, in order. A session's one-line chunks with a host time (a
        recording's every read) are framed as they come and handed on together, up to
        ``SESSION_RUN`` lines, to the assembler's batch (:meth:`_session_lines`); so are the
        lines of the runs of reads a bulk read of the raw log gives (:class:`Lines`, framed
        in one split, each line dated by the read that ended it); every other chunk goes
        through :meth:`feed` once the lines before it are."""
        done: list[TimedDescent] = []
        lines: list[str] = []
        hosts: list[float] = []
        framer = self.framer
        for item in chunks:
            group: Iterable[Chunk]
            if isinstance(item, Lines):  # reads of printable ASCII, with host times
                if item.ends is None:  # a line a read
                    got, ends = framer.feed_lines(item.rx), item.t
                else:  # the host time of each line: the read that ended it
                    got, ends = framer.feed_run(item.text), item.ends
                if got is None:  # a line too long: read by read
                    group = item.chunks()
                else:
                    self._chunk_t = item.t[-1]
                    k, n = 0, len(got)
                    while k < n:  # runs of SESSION_RUN lines for the batch
                        room = SESSION_RUN - len(lines)
                        lines += got[k : k + room]
                        hosts += ends[k : k + room]
                        k += room
                        if len(lines) >= SESSION_RUN:
                            done += self._hand_on(lines, hosts)
                    continue
            else:
                group = (item,)
            for chunk in group:
                t = chunk.t
                if not chunk.event and t is not None and t == t:
                    got = framer.feed(chunk.data)
                    self._chunk_t = t
                    if len(got) == 1:
                        lines.append(got[0])
                        hosts.append(t)
                        if len(lines) >= SESSION_RUN:
                            done += self._hand_on(lines, hosts)
                        continue
                    done += self._hand_on(lines, hosts)
                    for line in got:  # as feed does with a chunk of several lines (or none)
                        done += self._line(line, t)
                    continue
                done += self._hand_on(lines, hosts)
                done += self.feed(chunk)
        done += self._hand_on(lines, hosts)
        return done

    def _hand_on(self, lines: list[str], hosts: list[float]) -> list[TimedDescent]:
        """:meth:`_session_lines` of the batch :meth:`feed_chunks` gathered (nothing when it is
        empty), the batch then emptied in place for the lines that follow. Why: the batch is
        handed on when full, before a chunk of several lines, before any other chunk and at
        the end, and each of the four places had these lines."""
        if not lines:
            return []
        done = self._session_lines(lines, hosts)
        lines.clear()
        hosts.clear()
        return done

    def _session_lines(self, lines: list[str], hosts: list[float]) -> list[TimedDescent]:
        """:meth:`_parsed` for each line, ``hosts`` its host time (a number), with runs of
        impulses in the assembler's batch. What ``_parsed`` leaves for each impulse is left
        for the run: the offset of the device clock from the host's (by the last impulse the
        clock stood at), the recent lines, each start dated by its own line's host time and
        judged against the timer's clock."""
        done: list[TimedDescent] = []
        parsed_lines = self.parser.parse_lines(lines)
        asm = self.assembler
        feed_run, recent = asm.feed_run, self._recent
        i, n = 0, len(lines)
        stopped = -1  # the impulse the batch stopped at: fed on its own
        while i < n:
            if (
                i != stopped
                and type(parsed_lines[i]) is Impulse
                and self.resolution_us is not None
                and self.download_line is None  # (see _capture_lines)
            ):
                first = self.lines + 1  # the line number of parsed_lines[i]
                stop, ended, kept = feed_run(parsed_lines, i, first, self._dated(hosts, i - first))
                if stop > i:
                    self.lines += stop - i
                    self._count_impulses(stop - i)
                    if kept >= 0:
                        self._pair_clock(round(hosts[kept] * 1e6))
                    tail = max(i, stop - RECENT_LINES)
                    recent.extend(zip(range(first + tail - i, self.lines + 1),
                                      hosts[tail:stop], strict=True))  # fmt: skip
                    done += ended
                    i = stopped = stop
                    continue
            ended = self._parsed(lines[i], parsed_lines[i], hosts[i])
            if ended:
                done += ended
            i += 1
        return done

    def _dated(self, hosts: list[float], shift: int) -> Callable[[TimedDescent], None]:
        """What a start in the batch leaves: the host time of its line (``hosts[first_line +
        shift]``), and the start judged against the timer's clock."""
        start_host, judge = self.start_host, self._started

        def dated(d: TimedDescent) -> None:
            start_host[d.number] = hosts[d.first_line + shift]
            judge(d)

        return dated

    def _pair_clock(self, host_us: int) -> None:
        """The device clock stands at the time of the impulse that came at ``host_us``: their
        difference is the offset (the memory's own while the timer's memory comes: its
        times are not the timer's now)."""
        clock = self.assembler.clock
        assert clock is not None
        if self.assembler.from_memory:
            self.memory_offset_us = clock - host_us
        else:
            self.offset_us = clock - host_us

    def _line(self, line: str, t: float | None) -> list[TimedDescent]:
        return self._parsed(line, self.parser.parse(line), t)

    def _parsed(self, line: str, parsed: Parsed, t: float | None) -> list[TimedDescent]:  # noqa: C901 - every line's dispatch by kind, in one place
        """One line and what the parser made of it."""
        self.lines += 1
        if self.download_line is not None and isinstance(parsed, Impulse | Edit):
            self._live_after_download(parsed)
        if type(parsed) is Impulse:
            self._count_impulses(1)
            asm = self.assembler
            if self.resolution_us is None and parsed.channel in self._photocell_channels:
                self.resolution_us = parsed.resolution_us
            before = asm.count
            if t is None or t != t:  # a plain capture (or a NaN host time): no host clock
                done = asm.feed(parsed, self.lines, None)
            else:
                host_us = round(t * 1e6)
                offset = self._offset()
                # the device time now, by the host clock
                now = host_us + offset if offset is not None else None
                done = asm.feed(parsed, self.lines, now)
                clock = asm.clock
                # the offset pairs a device time with the host time of the line that carried
                # it: only an impulse kept (the clock moved to its time). A rejected or held one
                # leaves the clock at the last kept impulse, minutes back after an outage: paired
                # with this line's host time it put the estimate minutes wrong (every later time
                # far from the clock held for confirmation, time-outs late). The memory's kept
                # impulses have their own (they moved the live one to their old times likewise)
                if clock is not None and clock == asm.unwrap(parsed):
                    self._pair_clock(host_us)
            self._recent.append((self.lines, t))
            if asm.count > before:
                self._new_descents(before, done, t, judge=True)
            return done
        if isinstance(parsed, Edit):
            asm = self.assembler
            if parsed.kind == MEMORY_REPEAT:
                # ALGE `m`: an impulse from the timer's memory, laid out as an edit; counted
                # as the impulse it is (an import's summary called its memory lines edits)
                self.impulses += 1
                self.counts["memory"] += 1
            else:
                self.counts["edit"] += 1
            before = asm.count
            done = asm.edit(parsed, self.lines)
            self._recent.append((self.lines, t))
            if asm.count > before:  # a start typed in at the timer, or one from its memory
                self._new_descents(before, done, t, judge=False)
            return done
        if isinstance(parsed, Skip):
            self.counts["skipped"] += 1
            if parsed.reason in MEMORY_DOWNLOAD:  # TAG DS … DE sent over the line
                if MEMORY_DOWNLOAD[parsed.reason]:
                    done = self._memory_follows(t, fresh_clock=False)
                    self.download_line = self.lines
                    return done
                self._memory_ends()
        elif isinstance(parsed, Unparsed):
            self.counts["unparsed"] += 1
            # it may have been a skier's start: the assembler may start that descent later
            self.assembler.note_damaged(self.lines)
            if len(self.unparsed) < MAX_UNPARSED:
                self.unparsed.append((self.lines, parsed.reason, line[:100]))
            elif len(self.unparsed) == MAX_UNPARSED:  # said once, in the list itself
                self.unparsed.append(
                    (self.lines, "this and later unparsed lines not listed; see the raw log", "")
                )
        return []

    def _memory_ends(self) -> None:
        """The timer's memory is over (a ``DE``, a disconnect, a live time after a lost ``DE``):
        the impulses that follow are live again, and no download is on the line."""
        self.assembler.from_memory = False
        self.download_line = None

    def _live_after_download(self, parsed: Impulse | Edit) -> None:
        """A time message while a download is on the line (:attr:`download_line`): a live
        one (``TN`` new time, ``T+``/``T-``/… an edit at the timer: THCOM08 sends the memory
        as ``AN`` answers, the real CP540 capture ``DS``, ``AN``…, ``DE``, then ``T+``, ``TN``)
        means the ``DE`` was lost on the line: the memory ends before it, with an event that
        says so. Without it the rest of the day was taken as the timer's memory (its
        descents flagged as such, a live skier's crossings joined to memory descents). A time
        far past the download's last does not tell it: a day's memory has gaps of hours."""
        if parsed.line.lstrip("#")[:1] != "T" or not self.assembler.from_memory:
            return
        self._memory_ends()
        kind = parsed.line.lstrip("#")[:2]
        n = self.lines
        why = f"download end DE not seen; memory taken as ended at line {n} (a live {kind})"
        self.events.append(
            ImpulseEvent(self.lines, parsed.channel, None, parsed.tod_us, parsed.flag, False, why)
        )

    def _memory_follows(self, t: float | None, fresh_clock: bool) -> list[TimedDescent]:
        """Impulses from the timer's memory follow: a live impulse still held for the next
        one to confirm its time is taken first, as at the end of a capture (the memory's
        first impulse, earlier by nature, called it a corrupted time and it joined nothing:
        the live finish of a descent split by an unplugged cable was lost); then the
        assembler is told (:attr:`DescentAssembler.from_memory`)."""
        asm = self.assembler
        before = asm.count
        done = asm.memory_follows()
        if asm.count > before:
            self._new_descents(before, done, t, judge=True)
        if fresh_clock:
            self._latest_start = None
        self.memory_offset_us = None  # (the live estimate until the memory's first is kept)
        return done

    def _new_descents(
        self, before: int, done: list[TimedDescent], t: float | None, judge: bool
    ) -> None:
        """The assembler started descents ``before`` + 1 … its count in the call that handed
        back ``done``, by whatever path: a start impulse, a start it held until the next impulse
        confirmed it (two starts then come in one call, and the held one may already have
        finished), a start recovered after a damaged line, a start typed in at the timer or
        repeated from its memory. Each gets the host time of the line that started it, so it
        is dated live and in replay alike (:func:`station.session.analysis.start_time`); with
        ``judge``, each is checked against the timer's clock (:meth:`_started`)."""
        asm = self.assembler
        count = asm.count
        if count == before + 1 and asm.open and self._recent:  # the common case: one start,
            d = asm.open[-1]  # by the line last handed to the assembler
            line, host = self._recent[-1]
            if d.number == count and d.first_line == line:
                self.start_host[count] = host
                if judge:
                    self._started(d)
                return
        new = {d.number: d for d in (*asm.open, *done) if d.number > before}
        for number in range(before + 1, count + 1):
            d = new.get(number)
            host = t  # (the line that made the assembler start it, when not among the recent)
            if d is not None:
                host = next((h for ln, h in reversed(self._recent) if ln == d.first_line), t)
            self.start_host[number] = host
            if judge and d is not None:
                self._started(d)

    def _started(self, d: TimedDescent) -> None:
        """A descent started by the timer's impulses: one that starts before an earlier one by
        the timer's clock (the timer reset to 00:00, its clock set back) is flagged, since its
        start time then goes backwards in the results. A start typed in at the timer or
        repeated from its memory (a download merged after the day) is not judged: its time is
        not the clock's now, and comes after later ones by nature."""
        number = d.number
        if not d.times_us:
            return
        start = d.times_us[0]
        if self._latest_start is not None and start < self._latest_start[0]:
            back = (self._latest_start[0] - start) / 1e6
            amount = f"{back / 3600:.2f} h" if back >= 3600 else f"{back:.1f} s"
            d.flags.append(f"starts {amount} before descent {self._latest_start[1]} by the "
                           "timer's clock (was it reset or set back?): its start time goes "
                           "backwards")  # fmt: skip
        self._latest_start = (start, number)

    def tick(self, host_t: float) -> list[TimedDescent]:
        """Host time now: end a descent whose time-out passed on the device clock (while the
        timer's memory comes, by the memory's clock: its descents are hours old by the live
        one, and a tick after every read ended them mid-download)."""
        offset = self._offset()
        if offset is None:
            return []
        return self.assembler.tick(round(host_t * 1e6) + offset)

    def _offset(self) -> int | None:
        """Device clock − host clock in effect: the memory's while it comes and has one."""
        if self.assembler.from_memory and self.memory_offset_us is not None:
            return self.memory_offset_us
        return self.offset_us

    def finish(self) -> list[TimedDescent]:
        """End of the input: the unfinished last line, then the open descent."""
        done: list[TimedDescent] = []
        for line in self.framer.flush():  # it came with the latest bytes: their host time
            done += self._line(line, self._chunk_t)
        asm = self.assembler
        before = asm.count
        closed = asm.close()  # a start held for confirmation is taken as it is
        if asm.count > before:
            self._new_descents(before, closed, None, judge=True)
        return done + closed
