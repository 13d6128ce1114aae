"""Small file helpers shared by physlab's writers."""
from __future__ import annotations

import contextlib
import os
import re
import secrets
import time
from pathlib import Path

#: A temporary file untouched for this long (s) belongs to a writer that was killed; the next
#: write of the same target removes it. (A live writer keeps touching its file.)
STALE_TEMP_SECONDS = 600.0


def _temp_pattern(path, suffix):
    return re.compile(rf"^\.{re.escape(path.stem)}\.[0-9a-f]{{16}}{re.escape(suffix)}$")


def remove_stale_temps(path, suffix=".tmp", older_than=STALE_TEMP_SECONDS):
    """Delete the temporary files that :func:`atomic_write` left next to ``path`` when its
    writer was killed (``.<stem>.<16 hex><suffix>``, unmodified for ``older_than`` seconds).
    Returns the number removed."""
    path = Path(path)
    pattern, now, n = _temp_pattern(path, suffix), time.time(), 0
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return 0
    for e in entries:
        if not pattern.match(e.name):
            continue
        with contextlib.suppress(OSError):        # gone already, or not ours to remove
            if e.is_file(follow_symlinks=False) and now - e.stat().st_mtime > older_than:
                os.remove(e.path)
                n += 1
    return n


def atomic_write(path, write, suffix=".tmp"):
    """Call ``write(tmp_path)`` on a temporary file next to ``path``, then ``os.replace`` it
    onto ``path``: readers never see a half-written file, a failure leaves the previous
    ``path`` untouched and no temp file, and temp files of killed earlier writers of the same
    target are removed (:func:`remove_stale_temps`). ``suffix`` lets writers that choose a
    format by extension (imageio) see the right one. The file gets the usual mode
    ``0o666 & ~umask`` (created by ``os.open``, so the process umask is never changed).
    Returns ``path`` as a :class:`~pathlib.Path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(path, suffix)
    while True:
        tmp = path.parent / f".{path.stem}.{secrets.token_hex(8)}{suffix}"
        try:
            os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
            break
        except FileExistsError:                   # 2**64 names: practically never
            continue
    try:
        write(str(tmp))
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return path


def atomic_write_text(path, text, encoding="utf-8"):
    """Write ``text`` to ``path`` atomically (see :func:`atomic_write`)."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding=encoding))


def read_json(path):
    """The JSON value in ``path`` (UTF-8); ValueError naming the file and line if it is not
    valid JSON, FileNotFoundError if it is missing."""
    import json
    from pathlib import Path

    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON (line {e.lineno}: {e.msg})") from None


def write_json(path, value):
    """Write ``value`` as indented JSON, atomically (a failed write keeps the old file)."""
    import json

    return atomic_write_text(path, json.dumps(value, indent=1) + "\n")


class JsonDocument:
    """``save`` / ``load`` for a class that is a versioned JSON document.

    The class sets ``JSON_VERSION`` and defines ``to_dict()`` and
    ``from_dict(d, source=...)``; ``from_dict`` starts with :meth:`check_document`, so every
    error names its source (the file when loaded) and the field."""

    JSON_VERSION = 1

    def save(self, path):
        """Write as indented JSON, atomically (a failed write keeps the old file)."""
        return write_json(path, self.to_dict())

    @classmethod
    def load(cls, path):
        """Read a file written by :meth:`save`; errors name the file."""
        return cls.from_dict(read_json(path), source=str(path))

    @classmethod
    def check_document(cls, d, source):
        """ValueError naming ``source`` unless ``d`` is a JSON object of this version."""
        if not isinstance(d, dict):
            raise ValueError(f"{source}: expected a JSON object, got {type(d).__name__}")
        if d.get("version") != cls.JSON_VERSION:
            raise ValueError(f"{source}: 'version' must be {cls.JSON_VERSION}, got "
                             f"{d.get('version')!r}")
