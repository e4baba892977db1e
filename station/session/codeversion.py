"""The version of the code that computes results, the one key by which the caches made from
it (the fits in ``fits.jsonl``, the results CSV's state) tell whether they hold for the
station that reads them.

The key is the SHA-256 of the source itself (every module but the commands, the UI, the
reports and the season store, which do not compute results) and the version, not the files'
sizes and modification times: a copy, a checkout or a reinstall that changes no code keeps
every cache, and an edit that keeps a file's size and time (``cp -p``, ``rsync -t``, an archive)
is still seen. Walking the folder and reading the 0.8 MB costs what the stat calls did (2–3
ms), once a process.
"""

from __future__ import annotations

import hashlib
import os
from functools import cache

from station import __version__

#: the parts of the station whose code does not decide results
_NOT_RESULTS = frozenset({"cli", "ui", "store", "report"})


@cache
def code_version() -> str:
    """The SHA-256 of the results code's source (paths and bytes) and the version."""
    root = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
    h = hashlib.sha256(__version__.encode())
    for folder, dirs, files in os.walk(root):
        top = folder == root
        dirs[:] = sorted(
            d for d in dirs if not d.startswith((".", "__")) and not (top and d in _NOT_RESULTS)
        )
        for name in sorted(files):
            if not name.endswith(".py"):
                continue
            path = os.path.join(folder, name)
            with open(path, "rb") as fh:
                data = fh.read()
            rel = os.path.relpath(path, root).replace(os.sep, "/")
            h.update(f"\0{rel}\0{len(data)}\0".encode())
            h.update(data)
    return h.hexdigest()
