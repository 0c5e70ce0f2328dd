"""Files that a reader (or a crash) never sees half written."""

from __future__ import annotations

import os
from pathlib import Path


def write_text_atomic(path: Path, text: str, durable: bool = False) -> None:
    """Write text to a temporary file beside path, then rename it over path.

    durable: also fsync the file before the rename, so that after a power loss path holds either
    the old or the new content (the caller fsyncs the directory if the rename must survive too).
    A failed write (a full disk) leaves no temporary file behind; path keeps its old content.
    """
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as handle:
            handle.write(text)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
