"""Opening a fleet dataset (a directory or an `s3://bucket/prefix`): its files, their schema versions, and a DuckDB
connection with one view per table.

Each view reads `DEST/<table>/**/*.parquet` (an export's temporary files never end in `.parquet`) with the Hive
partitions `robot_id` (text) and `date` (a date), unions the files by column name (a 6- and a 7-axis robot share a
table) and always has every column of the current schema: a column that older files lack reads as null.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from typing import TYPE_CHECKING, Any

import pyarrow as pa

from plem.errors import PlemError
from plem.fleet import schema

if TYPE_CHECKING:
    import duckdb
    from fsspec import AbstractFileSystem

#: The current schema of each table, with the Hive partition columns (a 6-axis robot's joint columns).
PARTITION_FIELDS = (pa.field("robot_id", pa.string()), pa.field("date", pa.date32()))
_CURRENT: dict[str, pa.Schema] = {"rt_raw": schema.rt_raw(6), "rt_events": schema.rt_events(),
                                  "rt_monitor_stats": schema.rt_monitor_stats(), "joint_states": schema.joint_states(6),
                                  "segments": schema.segments()}
QUERY_HOW = 'the tables are {tables}; list a table\'s columns with `plem fleet query {dest} "DESCRIBE rt_raw"`'


class FleetError(PlemError):
    """A fleet dataset cannot be opened or queried."""


def current_schema(table: str) -> pa.Schema:
    """A table's columns now, with its partition columns (what a reader sees of every file)."""
    current = _CURRENT[table]
    return pa.schema([*current, *PARTITION_FIELDS], metadata=current.metadata)


@dataclass
class Dataset:
    """An opened DEST: where it is, its tables' files, and the DuckDB connection with their views."""

    dest: str
    filesystem: AbstractFileSystem
    files: dict[str, list[str]]
    connection: duckdb.DuckDBPyConnection
    #: The empty tables of the current schemas the views union with (DuckDB reads registered tables by reference).
    registered: dict[str, pa.Table] = field(default_factory=dict)

    def rows(self, query: str, parameters: list[Any] | None = None) -> tuple[list[str], list[tuple[Any, ...]]]:
        """Run `query` on the views: its columns and rows (none for a statement without a result)."""
        with self._failures(query):
            relation = self.connection.sql(query, params=parameters)
            return ([], []) if relation is None else (list(relation.columns), relation.fetchall())

    def frame(self, query: str, parameters: list[Any] | None = None) -> Any:
        """The result of `query` as a pandas DataFrame, its times in UTC."""
        with self._failures(query):
            relation = self.connection.sql(query, params=parameters)
            if relation is None:
                raise FleetError("The query returned no rows", what="a query with a result (SELECT …)",
                                 why=f"{query!r} is a statement without a result", how=self.query_how())
            frame = relation.df()
        for column in frame.columns:   # DuckDB hands TIMESTAMPTZ columns over as naive UTC
            if str(frame[column].dtype).startswith("datetime64[") and frame[column].dt.tz is None:
                frame[column] = frame[column].dt.tz_localize("UTC")
        return frame

    @contextmanager
    def _failures(self, query: str) -> Iterator[None]:
        """DuckDB's errors while a query binds or runs, as FleetErrors: a file of the dataset that is not whole
        Parquet, or a query DuckDB refuses."""
        import duckdb

        try:
            yield
        except duckdb.Error as error:
            text = str(error).strip()
            damaged = re.search(r"[Ff]ile '([^']+)'", text)
            if damaged and isinstance(error, duckdb.InvalidInputException | duckdb.IOException):
                raise FleetError("A file of the dataset cannot be read", what="whole Parquet files under "
                                 f"{self.dest} (an export renames each into place only once it is written)",
                                 why=f"{damaged.group(1)}: DuckDB: {text}", how=_damaged_how(damaged.group(1),
                                                                                             self.dest)) from None
            raise FleetError("The query failed", what="a query DuckDB can run over the dataset's tables",
                             why=f"DuckDB: {text}", how=self.query_how()) from None

    def query_how(self) -> str:
        """The HOW of a failed query: the tables, and how to list a table's columns."""
        return QUERY_HOW.format(tables=", ".join(schema.TABLES), dest=self.dest)

    def url(self, path: str) -> str:
        """A file's path as DuckDB reads it (with its scheme on object storage)."""
        return path if self.dest_scheme() == "" else f"{self.dest_scheme()}://{path}"

    def dest_scheme(self) -> str:
        """DEST's scheme (`s3`), empty for a local directory."""
        return self.dest.split("://", 1)[0] if "://" in self.dest else ""


def _damaged_how(path: str, dest: str) -> str:
    """How to set a damaged file aside and have its segment exported again (an export skips a segment whose
    `segments` row is in the dataset)."""
    parts = partition_values(path)
    segment_row = f"{dest}/segments/robot_id={parts.get('robot_id', '…')}/date=*/{path.rsplit('/', 1)[-1]}"
    return (f"move {path} out of {dest} (the rest is read without it); to export its segment again, move {segment_row} "
            f"out too and rerun `plem bag export BAG_DIR --to {dest}` while the segment's bag is kept")


def partition_values(path: str) -> dict[str, str]:
    """A file's Hive partition values from its path (`robot_id=…/date=…/`)."""
    return dict(part.split("=", 1) for part in path.split("/") if "=" in part)


def open_dataset(dest: str, tables: tuple[str, ...] = schema.TABLES) -> Dataset:
    """Open DEST: check it is a dataset and that no file of `tables` is of a newer schema, then make their views
    (a report opens only the tables it reads: every file's footer is read once per table)."""
    import duckdb

    filesystem, root = _filesystem(dest)
    files = {table: _table_files(filesystem, dest, root, table) for table in schema.TABLES}
    if not any(files.values()):
        raise FleetError(f"{dest} is not a fleet dataset", what="a dataset exported by `plem bag export BAG_DIR "
                         f"--to DEST`: one directory per table ({', '.join(schema.TABLES)}) of .parquet files",
                         why=f"{dest} holds no .parquet file under any of those directories",
                         how="pass the DEST given to `plem bag export --to` or `export_dir:=`, or export the bags "
                             "first: plem bag export BAG_DIR --to DEST")
    connection = duckdb.connect()
    connection.execute("SET TimeZone = 'UTC'")
    connection.execute("SET parquet_metadata_cache = true")   # the footers read by the version check serve every view
    dataset = Dataset(dest, filesystem, files, connection)
    if dataset.dest_scheme():
        connection.register_filesystem(filesystem)
    _check_versions(dataset, tables)
    for table in tables:
        _create_view(dataset, table)
    return dataset


def _filesystem(dest: str) -> tuple[AbstractFileSystem, str]:
    """The fsspec filesystem of DEST and DEST's path on it; a local DEST must be an existing directory."""
    import fsspec

    if "://" not in dest:
        if not os.path.isdir(dest):
            why = f"{dest} is a file" if os.path.exists(dest) else f"{dest} does not exist"
            raise FleetError(f"No fleet dataset at {dest}", what="DEST: the directory (or s3://bucket/prefix) a "
                             "fleet's bags were exported to", why=why,
                             how="pass the DEST given to `plem bag export --to` or `export_dir:=`, e.g. "
                                 "plem fleet query /data/fleet \"SELECT count(*) FROM segments\"")
        return fsspec.filesystem("file"), os.path.abspath(dest)
    scheme, _, path = dest.partition("://")
    try:
        filesystem = fsspec.filesystem(scheme)
    except (ImportError, ValueError) as error:
        raise FleetError(f"Cannot open {dest}", what="DEST as a directory or an s3://bucket/prefix",
                         why=f"no filesystem for {scheme}://: {error}",
                         how="install the object-store support: pip install 'plem[s3]'") from None
    return filesystem, path.rstrip("/")


def _table_files(filesystem: AbstractFileSystem, dest: str, root: str, table: str) -> list[str]:
    """Every whole file of a table (`.parquet` only: an export's temporary files are named otherwise)."""
    try:
        found = filesystem.glob(f"{root}/{table}/**/*.parquet")
    except Exception as error:  # noqa: BLE001 - every store fails its own way; all mean DEST cannot be listed
        raise _access_error(dest, error) from None
    return sorted(str(path) for path in found)


def _access_error(dest: str, error: Exception) -> FleetError:
    """Listing DEST failed: missing credentials, access denied, or an unreachable store."""
    text = f"{type(error).__name__}: {error}"
    credentials = "credential" in text.lower() or "NoCredentials" in text
    why = ("no credentials were found for the object store (" + text + ")") if credentials else text
    how = ("set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or AWS_PROFILE), and AWS_ENDPOINT_URL for a store other "
           "than AWS S3, then rerun") if credentials else \
        "check DEST, the credentials in AWS_ACCESS_KEY_ID/AWS_SECRET_ACCESS_KEY and AWS_ENDPOINT_URL, and the network"
    return FleetError(f"Cannot read {dest}", what=f"to list the dataset's files under {dest}", why=why, how=how)


def _check_versions(dataset: Dataset, tables: tuple[str, ...]) -> None:
    """Refuse files written by a newer plem (they may hold columns this one reads wrongly); accept older ones."""
    urls = [dataset.url(path) for table in tables for path in dataset.files[table]]
    if not urls:
        return
    _, rows = dataset.rows("SELECT file_name, decode(value) FROM parquet_kv_metadata(?) WHERE decode(key) = ?",
                           [urls, schema.VERSION_KEY.decode()])
    newer = [(name, version) for name, version in rows if _version(version) > schema.SCHEMA_VERSION]
    if newer:
        name, version = newer[0]
        raise FleetError("The dataset holds files of a newer schema", what=f"files of schema version "
                         f"{schema.SCHEMA_VERSION} or older (this plem reads those)",
                         why=f"{len(newer)} file(s) of a newer version, e.g. {name} (version {version})",
                         how="upgrade plem on this machine (pip install -U plem) to read them; nothing was changed")


def _version(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        return schema.SCHEMA_VERSION + 1   # unreadable: treat as not ours to read


def _create_view(dataset: Dataset, table: str) -> None:
    """The table's view: its files unioned by name with an empty table of the current schema (missing columns
    read as null; a table without files is an empty view of the right columns)."""
    empty = current_schema(table).empty_table()
    dataset.registered[table] = empty
    dataset.connection.register(f"_{table}_columns", empty)
    urls = [dataset.url(path) for path in dataset.files[table]]
    if not urls:
        dataset.connection.execute(f"CREATE VIEW {table} AS SELECT * FROM _{table}_columns")
        return
    listing = ", ".join("'" + url.replace("'", "''") + "'" for url in urls)
    dataset.rows(f"CREATE VIEW {table} AS SELECT * FROM read_parquet([{listing}], hive_partitioning = true, "
                f"union_by_name = true, hive_types = {{'robot_id': VARCHAR, 'date': DATE}}) "
                f"UNION ALL BY NAME SELECT * FROM _{table}_columns")


def parse_since(text: str, now: datetime) -> datetime:
    """`--since`: a date or time (2026-11-01, 2026-11-01T08:00) in UTC, or a duration back from now (7d, 12h, 30m)."""
    units = {"d": "days", "h": "hours", "m": "minutes", "s": "seconds", "w": "weeks"}
    value = text.strip()
    if value[-1:] in units and value[:-1].replace(".", "", 1).isdigit():
        return now - timedelta(**{units[value[-1]]: float(value[:-1])})
    try:
        moment = datetime.fromisoformat(value)
    except ValueError:
        raise FleetError(f"--since {text!r} is not a date or a duration",
                         what="--since as a date (2026-11-01), a UTC time (2026-11-01T08:00) or a duration back "
                              "from now (7d, 12h, 30m, 2w)",
                         why=f"{text!r} is neither", how="pass e.g. --since 7d or --since 2026-11-01") from None
    return moment if moment.tzinfo else moment.replace(tzinfo=UTC)
