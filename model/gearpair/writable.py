"""Output files checked before a run: a command that learns only after minutes of work that it
cannot write its result has wasted the run.

`check_writable` is what ``gearpair simulate --out/--plot``, ``gearpair sweep --out`` and
``gearpair bench --plot`` call on each file they will write, before they start.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def check_writable(flag: str, path: str | Path, shown: str | None = None) -> Path:
    """Make sure the file ``path`` (given with option ``flag``) can be written later.

    Creates its folder if missing (as the commands do when they write). Raises
    ``ValueError`` with one line naming ``flag`` and the value as given (``shown``, default
    ``path``) when the path is a folder, its folder cannot be created, nothing can be
    created in its folder, or the file exists and is read only. Writes nothing else: the
    probe is a temporary file removed at once.
    """
    p = Path(path)
    given = f"{flag} {shown if shown is not None else path}"
    if not str(path).strip():
        raise ValueError(f"{flag}: give a file name (empty)")
    if p.is_dir():
        if shown is None:
            raise ValueError(f"{given}: is a folder; give a file name")
        raise ValueError(f"{given}: {p}, which it would write, is a folder")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{given}: cannot create its folder {p.parent} "
                         f"({exc.strerror or exc})") from None
    if p.exists():
        if not os.access(p, os.W_OK):
            raise ValueError(f"{given}: {p} exists and is not writable")
        return p
    try:
        tempfile.TemporaryFile(dir=p.parent, prefix=".gearpair_probe_").close()
    except OSError as exc:
        raise ValueError(f"{given}: cannot write in its folder {p.parent} "
                         f"({exc.strerror or exc})") from None
    return p
