"""A site's record over months: every event, each person's floor position once a second and their summary, the
gaps where nothing was seen, in a database that restarts append to (SQLite by default, PostgreSQL when given).
``RunRecorder`` writes a live run's record as it happens; ``read_record`` reads it back over a period."""

from ray3d.store.database import connect, is_postgresql
from ray3d.store.reader import StoredRecord, copy_record, floor_decisions, read_record
from ray3d.store.schema import SCHEMA_VERSION
from ray3d.store.writer import Resume, RunRecorder

__all__ = ["RunRecorder", "Resume", "StoredRecord", "read_record", "copy_record", "floor_decisions", "connect",
           "is_postgresql", "SCHEMA_VERSION"]
