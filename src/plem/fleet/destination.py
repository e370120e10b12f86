"""Where a fleet dataset is written: a local directory, or an S3-compatible object store through fsspec (s3fs).

A file reaches a reader whole or not at all. Locally it is written under a hidden temporary name that does
not end in `.parquet` (`.NAME.parquet.tmp-PID`) and renamed into place, so a reader globbing `**/*.parquet`
never sees half a file; the file and its directory are flushed, so the files of a segment are on disk before its
`segments` row is written. Temporary files a killed export left behind are removed by the next export. On S3 an
object appears only once its upload completes, so it is put whole under its final key.

This module imports no pyarrow and no s3fs at import time: the launch validates `export_dir:=` with it.
"""

from __future__ import annotations

import contextlib
import errno
import importlib.util
import os
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from plem.errors import PlemError

#: A temporary file's name: `.NAME.tmp-PID`.
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.tmp-(?P<pid>\d+)$")
_S3_ENVIRONMENT = "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (with AWS_ENDPOINT_URL for a store other than AWS, " \
                  "AWS_DEFAULT_REGION for a region)"


class DestinationError(PlemError):
    """A dataset destination that cannot be written."""


def is_s3(text: str) -> bool:
    """Whether a destination names an S3 prefix (`s3://bucket/prefix`)."""
    return text.startswith("s3://")


def destination_problem(text: str, argument: str) -> DestinationError | None:
    """What is wrong with a destination as given (`argument` names it: `--to`, `export_dir:=`), without touching
    it: an empty text, an S3 URL without a bucket, s3fs missing; None when it may be tried."""
    if not text.strip():
        return DestinationError("no dataset destination given", what="a directory, or s3://BUCKET/PREFIX",
                                why=f"{argument} is empty", how=f"pass e.g. {argument}/data/fleet")
    if "\0" in text:
        return DestinationError("the dataset destination holds a NUL byte", what="a directory, or s3://BUCKET/PREFIX",
                                why=f"{argument} contains a NUL byte", how=f"pass e.g. {argument}/data/fleet")
    if not is_s3(text):
        return None
    if not text.removeprefix("s3://").split("/", 1)[0]:
        return DestinationError(f"{text} names no bucket", what="s3://BUCKET or s3://BUCKET/PREFIX",
                                why="nothing between s3:// and the next /", how=f"pass e.g. {argument}s3://fleet/bags")
    if importlib.util.find_spec("s3fs") is None:
        return DestinationError("S3 support is not installed", what="the s3fs package, to write s3:// destinations",
                                why="import s3fs fails: plem was installed without its s3 extra",
                                how="pip install 'plem[s3]'")
    return None


@dataclass(frozen=True)
class Destination:
    """A dataset's root: `root` is a local directory path, or `bucket/prefix` on `fs` (an s3fs file system)."""

    text: str
    root: str
    fs: Any = None                                   # s3fs.S3FileSystem, None for a local directory

    @property
    def local(self) -> bool:
        """Whether the dataset is a local directory."""
        return self.fs is None

    def path(self, relative: str) -> str:
        """The full path (local) or key (S3) of a file of the dataset."""
        return f"{self.root.rstrip('/')}/{relative}"

    def put(self, relative: str, data: bytes) -> None:
        """Write one file whole under `relative` (replacing one of the same name): never seen half written."""
        if self.fs is not None:
            with _s3_errors(self):
                self.fs.pipe_file(self.path(relative), data)
            return
        final = Path(self.path(relative))
        temporary = final.with_name(f".{final.name}.tmp-{os.getpid()}")
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            with open(temporary, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.replace(temporary, final)
            directory = os.open(final.parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            try:
                os.fsync(directory)                  # the rename too survives a power loss before the next file
            finally:
                os.close(directory)
        except OSError as error:
            with contextlib.suppress(OSError):
                temporary.unlink()
            raise _local_problem(self, error) from None

    def names(self, relative: str) -> set[str]:
        """The names of the `.parquet` files anywhere under `relative` (none when it does not exist)."""
        if self.fs is not None:
            with _s3_errors(self):
                self.fs.invalidate_cache()           # another process may have exported since
                found = self.fs.glob(self.path(f"{relative}/**/*.parquet"))
            return {str(key).rsplit("/", 1)[-1] for key in found}
        base = Path(self.path(relative))
        return {path.name for path in base.rglob("*.parquet")} if base.is_dir() else set()

    def free_share(self) -> tuple[int, int] | None:
        """(total, used) bytes of the file system holding a local dataset; None on S3."""
        if self.fs is not None:
            return None
        total, used, _ = shutil.disk_usage(self.root)
        return total, used

    def remove_temporaries(self) -> list[str]:
        """Delete the temporary files exports killed before their rename left (not those of a live export); their
        paths."""
        if self.fs is not None:
            return []                                # objects are put whole: there are none
        removed = []
        for path in _temporaries(Path(self.root)):
            match = _TEMPORARY.match(path.name)
            if match is None or _alive(int(match["pid"])):
                continue
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
                removed.append(str(path))
        return removed


def _temporaries(root: Path) -> Iterator[Path]:
    for directory, _, files in os.walk(root):
        for name in files:
            if name.startswith(".") and ".tmp-" in name:
                yield Path(directory) / name


def _alive(pid: int) -> bool:
    """Whether a process of that id runs (a temporary file of a live export on this host is left alone)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def open_destination(text: str, argument: str = "--to ") -> Destination:
    """The destination `text` ready to write: a local directory created when missing and proven writable, or an S3
    prefix whose bucket exists and takes a write; DestinationError (WHAT/WHY/HOW) otherwise."""
    problem = destination_problem(text, argument)
    if problem is not None:
        raise problem
    if is_s3(text):
        return _open_s3(text, argument)
    destination = Destination(text, str(Path(text).expanduser()))
    root = Path(destination.root)
    if root.exists() and not root.is_dir():
        raise DestinationError(f"{root} is not a directory", what="a directory for the dataset (created when missing)",
                               why="it is a file", how=f"pass another path: {argument}DIR")
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = root / f".probe.tmp-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise _local_problem(destination, error) from None
    return destination


def _local_problem(destination: Destination, error: OSError) -> DestinationError:
    """A local write that failed, in the user's words."""
    where = error.filename or destination.root
    why = f"{where}: {error.strerror or error}"
    if error.errno in (errno.ENOSPC, errno.EDQUOT):
        how = "free space there, or pass another destination; what is exported stays and the next run goes on"
    elif error.errno == errno.ENOTDIR:
        how = f"a file is in the way: move it, or pass another path ({destination.text} names a directory)"
    else:
        how = f"give your user write access to {destination.root}, or pass a directory you can write"
    return DestinationError(f"cannot write the dataset into {destination.root}",
                            what="a directory your user may create files in", why=why, how=how)


def _open_s3(text: str, argument: str) -> Destination:
    import s3fs

    bucket_and_prefix = text.removeprefix("s3://").rstrip("/")
    bucket = bucket_and_prefix.split("/", 1)[0]
    endpoint = os.environ.get("AWS_ENDPOINT_URL") or os.environ.get("AWS_ENDPOINT_URL_S3")
    options: dict[str, Any] = {"client_kwargs": {"endpoint_url": endpoint}} if endpoint else {}
    if not (os.environ.get("AWS_ACCESS_KEY_ID") and os.environ.get("AWS_SECRET_ACCESS_KEY")) \
            and not os.environ.get("AWS_PROFILE") and not Path("~/.aws/credentials").expanduser().exists():
        raise DestinationError(f"no S3 credentials for {text}", what=f"credentials for the store: {_S3_ENVIRONMENT}",
                               why="none of them is set, and there is no AWS_PROFILE or ~/.aws/credentials",
                               how="export AWS_ACCESS_KEY_ID=... AWS_SECRET_ACCESS_KEY=... (and AWS_ENDPOINT_URL=... "
                                   "for a store other than AWS), then run the export again")
    destination = Destination(text, bucket_and_prefix, s3fs.S3FileSystem(**options))
    with _s3_errors(destination):
        if not destination.fs.exists(bucket):
            raise DestinationError(f"bucket {bucket} does not exist", what=f"an existing bucket for {text}",
                                   why=f"the store at {endpoint or 'AWS'} has no bucket {bucket}",
                                   how=f"create it (aws s3 mb s3://{bucket}), or pass another bucket in {argument}")
    return destination


@contextlib.contextmanager
def _s3_errors(destination: Destination) -> Iterator[None]:
    """s3fs and botocore errors as one WHAT/WHY/HOW naming the destination."""
    try:
        yield
    except PlemError:
        raise
    except PermissionError as error:
        raise DestinationError(f"the store refuses access to {destination.text}", what="credentials allowed to list "
                               "and put objects there", why=str(error) or "access denied",
                               how=f"check {_S3_ENVIRONMENT}") from None
    except (OSError, ValueError) as error:
        raise DestinationError(f"cannot write the dataset to {destination.text}",
                               what="an S3-compatible store that takes the objects",
                               why=str(error) or type(error).__name__,
                               how=f"check the endpoint and credentials ({_S3_ENVIRONMENT}), then run the export "
                                   "again: what is exported stays") from None
    except Exception as error:      # botocore's own (NoCredentialsError, EndpointConnectionError, ClientError)
        if type(error).__module__.split(".")[0] not in ("botocore", "aiobotocore", "s3fs"):
            raise
        raise DestinationError(f"cannot reach the dataset at {destination.text}",
                               what="an S3-compatible store that answers with these credentials",
                               why=f"{type(error).__name__}: {error}",
                               how=f"check the endpoint and credentials ({_S3_ENVIRONMENT})") from None
