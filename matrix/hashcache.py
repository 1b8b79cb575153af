"""The fingerprints' memory across processes: one small SQLite file (see HashCache)."""
from __future__ import annotations

import json
import os
from pathlib import Path


class HashCache:
    """sha256 of input files remembered across processes by (path, size, mtime, inode), as DVC does,
    in a small SQLite file: `$MATRIX_HASH_CACHE`, else `$XDG_CACHE_HOME/matrix/file_hashes.sqlite`
    (`~/.cache/...`). Only files of at least `min_size` bytes are kept (smaller ones hash faster than a
    look-up). The same file remembers the import names of source files by the sha256 of their text,
    and whole module closures with what they were read from, checked before use (`module_closure`).
    A cache that cannot be opened or written is ignored: it only saves time."""

    def __init__(self, min_size: int = 1 << 20):
        self.min_size, self._db, self._broken, self._pid = min_size, None, False, 0

    @staticmethod
    def location() -> Path:
        if os.environ.get("MATRIX_HASH_CACHE"):
            return Path(os.environ["MATRIX_HASH_CACHE"])
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        return Path(base) / "matrix" / "file_hashes.sqlite"

    def get(self, marker: tuple) -> str | None:
        if marker[1] < self.min_size:
            return None
        row = self._query("SELECT sha256 FROM hashes WHERE path=? AND size=? AND mtime_ns=? AND inode=?", marker)
        return row[0] if row else None

    def put(self, marker: tuple, sha256: str) -> str:
        if marker[1] >= self.min_size:
            self._query("INSERT OR REPLACE INTO hashes VALUES (?, ?, ?, ?, ?)", (*marker, sha256), commit=True)
        return sha256

    def get_names(self, key: str) -> list[str] | None:
        """The import names remembered for a source text's sha256 (`_import_names`)."""
        row = self._query("SELECT names FROM imports WHERE key=?", (key,))
        return row[0].split() if row else None

    def put_names(self, key: str, names: list[str]) -> None:
        """Remember them (committed by `commit`: one transaction for a closure's new files)."""
        self._query("INSERT OR REPLACE INTO imports VALUES (?, ?)", (key, " ".join(names)))

    def get_closure(self, key: str) -> dict | None:
        """A module closure remembered under `key`, with the facts it was read from (not yet checked)."""
        row = self._query("SELECT record FROM closures WHERE key=?", (key,))
        try:
            record = json.loads(row[0]) if row else None
        except ValueError:   # a damaged row is only a miss
            return None
        return record if isinstance(record, dict) and isinstance(record.get("modules"), list) else None

    def put_closure(self, key: str, record: dict) -> None:
        """Remember it (committed by `commit`)."""
        self._query("INSERT OR REPLACE INTO closures VALUES (?, ?)", (key, json.dumps(record)))

    def commit(self) -> None:
        import sqlite3
        try:
            if self._db is not None and self._pid == os.getpid() and not self._broken:
                self._db.commit()
        except sqlite3.Error:
            self._broken = True

    def _query(self, sql: str, args: tuple, commit: bool = False):
        import sqlite3
        try:
            db = self._connect()
            if db is None:
                return None
            row = db.execute(sql, args).fetchone()
            if commit:
                db.commit()
            return row
        except (sqlite3.Error, OSError):
            self._broken = True
            return None

    def _connect(self):
        import sqlite3
        if self._pid != os.getpid():   # a forked child never uses its parent's connection
            self._db, self._pid = None, os.getpid()
        if self._db is None and not self._broken:
            location = self.location()
            location.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(location, timeout=5)
            self._db.execute("CREATE TABLE IF NOT EXISTS hashes (path TEXT PRIMARY KEY, size INTEGER, "
                             "mtime_ns INTEGER, inode INTEGER, sha256 TEXT)")
            self._db.execute("CREATE TABLE IF NOT EXISTS imports (key TEXT PRIMARY KEY, names TEXT)")
            self._db.execute("CREATE TABLE IF NOT EXISTS closures (key TEXT PRIMARY KEY, record TEXT)")
        return self._db


HASH_CACHE = HashCache()
