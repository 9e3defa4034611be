"""One writer per store (``WriterLock``): a second live run on a store another one writes would take it up at the
first one's last commit and both would write the same record and events.jsonl. The lock is one the system gives
back when its holder dies, so a process killed outright (SIGKILL, OOM, a power cut) never blocks its restart:

- SQLite: ``fcntl.flock`` on a file beside the store (``site.db.lock``), released by the kernel with the process;
- PostgreSQL: a session-level advisory lock (``pg_try_advisory_lock``) on a connection of its own, released by the
  server when the connection drops.

Who holds it (pid, host, when it started) is kept in the store's ``store_meta`` (``writer``), written once the lock
is taken, so that the one refused can name the one running."""

from __future__ import annotations

import datetime
import json
import os
import socket
import time
from pathlib import Path

from ray3d.errors import InputError
from ray3d.store.database import Database, is_postgresql, shown

WRITER_LOCK = 7_146_302  # PostgreSQL advisory lock of the one writer (database.SCHEMA_LOCK is another)


def lock_path(location) -> Path:
    """The file an SQLite store's writer holds its lock on: beside the store."""
    return Path(f"{location}.lock")


class WriterLock:
    """Held by the one process that writes the store at ``location`` from ``take`` to ``release``; ``take``
    refuses (``InputError`` naming the holder) while another process holds it."""

    def __init__(self, location):
        self.location, self.postgresql = location, is_postgresql(location)
        self._held = None  # the lock file's descriptor, or the PostgreSQL connection holding the lock

    def take(self) -> None:
        if self.postgresql:
            # A session-level lock outlives the transaction it was taken in; it goes when the connection does.
            database = Database(self.location)
            taken = database.rows("SELECT pg_try_advisory_lock(?)", (WRITER_LOCK,))[0][0]
            database.commit()
            if not taken:
                database.close()
                self._refuse()
            self._held = database
            return
        import fcntl

        path = lock_path(self.location)
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(descriptor)
            self._refuse()
        self._held = descriptor

    def note_holder(self, database: Database) -> None:
        """This process noted in the store as its writer (for the message of the one refused)."""
        holder = {"pid": os.getpid(), "host": socket.gethostname(), "started_at": time.time()}
        database.execute("DELETE FROM store_meta WHERE name = 'writer'")
        database.execute("INSERT INTO store_meta (name, value) VALUES ('writer', ?)", (json.dumps(holder),))

    def _refuse(self):
        holder = None
        try:
            if self.postgresql or Path(self.location).is_file():
                database = Database(self.location)
                try:
                    found = database.rows("SELECT value FROM store_meta WHERE name = 'writer'")
                finally:
                    database.close()
                holder = json.loads(found[0][0]) if found else None
        except Exception:  # the store unreadable now: the refusal stands, without the holder's name
            pass
        if holder:
            started = datetime.datetime.fromtimestamp(holder["started_at"]).astimezone().isoformat(timespec="seconds")
            who = f"ray3d live (pid {holder['pid']} on {holder['host']}, started {started})"
        else:
            who = "another ray3d live, starting"
        raise InputError(f"store: {shown(self.location)}: {who} writes it; one process writes a store at a time: "
                         "stop that one first, or give this run another store", ("store",))

    def release(self) -> None:
        """Given back (closing again does nothing)."""
        held, self._held = self._held, None
        if held is None:
            return
        if self.postgresql:
            held.close()  # the session's advisory lock goes with its connection
        else:
            os.close(held)  # the flock goes with the last descriptor of the open file
