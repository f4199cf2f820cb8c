"""Where results are written, and the rules that keep them whole.

- `output_problem(path)` says, before any work, why a file cannot be written at `path`
  (empty, NUL or control characters, a directory, a parent that is missing or not a
  directory, a read-only place, a name too long for the file system).
- `OutputLock` holds an exclusive lock on `<path>.lock` (flock: released by the kernel if the
  process dies), so two runs never write one output; the second is refused naming the first.
- `create_partial(path)` makes `<path>.partial` exclusively (O_EXCL | O_NOFOLLOW): never
  through a symlink, never over another run's frames.
- `publish(partial, path)` renames the finished file into place atomically.
- `replaced(path)` gives every other output (charts, pictures, tables, scene copies, recordings) a
  fresh temporary name beside `path`, renamed onto it when whole: no command writes through a
  link it did not make (the rename replaces a planted link itself), and none leaves half a file.
  `replaced_together(paths)` does the same for files written as one (an XDMF export and its data).
- `clobber_problems(outputs, inputs)` says which outputs are files the command reads (by identity:
  the same device and inode, so a hard link or a symlink to one too): every command refuses them
  before any work, whatever the output (a trajectory, a chart, --json, a lock).
"""

from __future__ import annotations

import errno
import fcntl
import os
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

NAME_MAX = 255  # bytes in one path component on Linux file systems
PATH_MAX = 4096  # bytes in a whole path on Linux, its terminating NUL included
MIN_FREE_BYTES = 1 << 16  # a device with less free space than this is full: refused before any work
_statvfs = os.statvfs  # bound once: the writer's own free-space checks (h5md) are separate


class OutputError(Exception):
    """An output cannot be written; the message is one line for the user."""


def text_problem(text: str) -> str | None:
    """Why a path or name string is unusable (NUL or control characters), or None."""
    bad = next((c for c in text if ord(c) < 32 or ord(c) == 127), None)
    if bad is not None:
        return f"contains a control character ({bad!r})"
    return None


def _length_problem(text: str) -> str | None:
    """Why the system would refuse `text` as a path for its length (a component over NAME_MAX bytes,
    the whole over PATH_MAX), or None."""
    longest = max(Path(text).parts, key=lambda part: len(part.encode()), default="")
    if len(longest.encode()) > NAME_MAX:
        return f"a name in it is too long ({len(longest.encode())} bytes; at most {NAME_MAX})"
    if len(os.path.abspath(text).encode()) >= PATH_MAX:
        return f"path is too long ({len(os.path.abspath(text).encode())} bytes; less than {PATH_MAX})"
    return None


def output_problem(path, suffixes=(".partial", ".lock")) -> str | None:
    """Why a file cannot be created or replaced at `path`, or None. `suffixes`: sidecar names
    that must fit too."""
    text = os.fspath(path)
    problem = "is empty" if text == "" else text_problem(text)
    if problem:
        return problem
    problem = _length_problem(os.path.dirname(text) or ".")
    if problem:
        return problem
    p = Path(text)
    if text.endswith(os.sep) or p.name in ("", ".", ".."):
        return "names a directory, not a file"
    longest = max((len((p.name + s).encode()) for s in ("", *suffixes)))
    if longest > NAME_MAX:  # first: a longer name makes stat itself fail
        return f"file name is too long ({longest} bytes with its {'/'.join(suffixes)} sidecars; at most {NAME_MAX})"
    if p.is_dir():
        return "is a directory"
    kind = _special_kind(p)
    if kind:
        return f"exists and is not a regular file ({kind}); refusing to replace it"
    return _place_problem(p.parent)


def _special_kind(path: Path) -> str | None:
    """What `path` is when it exists and is neither a regular file, a directory nor a link: a device,
    a FIFO or a socket (a run with -o /dev/null must not replace the system's /dev/null)."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    for test, kind in ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return None


def directory_problem(path) -> str | None:
    """Why `path` cannot be used (or created) as an output directory, or None."""
    text = os.fspath(path)
    problem = "is empty" if text == "" else text_problem(text) or _length_problem(text)
    return problem or _place_problem(Path(text))


def _place_problem(directory: Path) -> str | None:
    """Why nothing can be created at `directory` (made if missing): its nearest existing
    ancestor must be a directory we may write in."""
    for ancestor in (directory, *directory.parents):
        if ancestor.exists():
            if not ancestor.is_dir():
                return f"{ancestor} is not a directory"
            if not os.access(ancestor, os.W_OK | os.X_OK):
                return f"cannot write in {ancestor} (read-only or no permission)"
            return _creation_problem(ancestor)
    return None


def _creation_problem(directory: Path) -> str | None:
    """Why no file can be created in `directory` though its permissions allow it (/proc, a read-only
    mount, a full disk, as root): found by creating one, then removing it."""
    try:
        fd, name = tempfile.mkstemp(dir=directory, prefix=".blobsim-probe-")
    except OSError as e:
        return f"cannot create a file in {directory} ({os.strerror(e.errno) if e.errno else e})"
    os.close(fd)
    os.unlink(name)
    try:
        free = _statvfs(directory)
    except OSError:
        return None
    if free.f_bavail * free.f_frsize < MIN_FREE_BYTES:
        return f"no space left on the device holding {directory}"
    return None


class OutputLock:
    """An exclusive advisory lock on `<path>.lock` for the life of a run."""

    def __init__(self, path):
        self.path = Path(path)
        self.lock_path = self.path.with_name(self.path.name + ".lock")
        self.fd = None

    def __enter__(self):
        self.lock_path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            try:
                fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
            except OSError as e:
                what = "is a symlink" if e.errno == errno.ELOOP else f"cannot be created ({os.strerror(e.errno)})"
                raise OutputError(f"{self.lock_path}: {what}; refusing to write {self.path}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise OutputError(f"{self.path}: another blobsim run (pid {holder}) is writing this file; "
                                  f"wait for it or choose another -o") from None
            # The holder before us may have removed the lock file after we opened it: then
            # our lock is on a file nobody else will see. Lock the file that is there now.
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.lock_path, follow_symlinks=False))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        self.fd = fd
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        except OSError as e:  # a full disk: no lock left behind
            self.__exit__()
            raise OutputError(f"{self.lock_path}: cannot write ({os.strerror(e.errno)})") from None
        return self

    def __exit__(self, *exc):
        try:
            os.unlink(self.lock_path)  # while still holding it, so no one locks a removed file
        except FileNotFoundError:
            pass
        os.close(self.fd)
        self.fd = None


def create_partial(path) -> Path:
    """Create `<path>.partial` exclusively and return its path. Refused if anything (a file, a
    symlink) is already there: it may hold the frames of a run that was killed."""
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        fd = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except FileExistsError:
        kind = "a symlink" if partial.is_symlink() else "a file"
        raise OutputError(f"{partial}: already exists ({kind}), perhaps the frames of a run that was killed; "
                          f"move it away (a killed run's file can be continued with --resume) or delete it") from None
    except OSError as e:
        raise OutputError(f"{partial}: cannot create ({os.strerror(e.errno)})") from None
    os.close(fd)
    return partial


def publish(partial: Path, path: Path) -> None:
    """Move the finished file into place (atomic on one file system)."""
    try:
        os.replace(partial, path)
    except OSError as e:
        if e.errno == errno.EISDIR:
            raise OutputError(f"{path}: is a directory; the run's frames are in {partial}") from None
        raise OutputError(f"{path}: cannot replace ({os.strerror(e.errno)}); "
                          f"the run's frames are in {partial}") from None


@contextmanager
def replaced(path):
    """Yield a fresh temporary path beside `path` (same suffix, created exclusively) to write the
    whole output to; when the block ends without error it is renamed onto `path` (replacing a link
    there, never writing through it), else removed."""
    path = Path(path)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix or ".tmp")
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(name, 0o666 & ~umask)  # as an ordinary new file, not mkstemp's 0600
    try:
        yield Path(name)
        os.replace(name, path)
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise


@contextmanager
def replaced_together(paths):
    """`replaced` for files written as one (an XDMF file names its heavy data): yield a fresh hidden
    directory beside them (they share a directory) to write each in under its own name; when the
    block ends without error each is renamed onto its path, else none is."""
    paths = [Path(p) for p in paths]
    work = Path(tempfile.mkdtemp(prefix=f".{paths[0].name}.", dir=paths[0].parent))
    try:
        yield work
        for path in paths:
            os.replace(work / path.name, path)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def clobber_problems(outputs, inputs) -> list[tuple[str, str]]:
    """(output, why) for each of `outputs` that is one of `inputs`, (path, what it is) pairs of the files the
    command reads ("the scene", ...): the same file by identity (device and inode, as os.path.samefile: a hard
    link or a symlink to it too), or, for an input not there yet (a trajectory the command writes and then
    reads), the same real path. Every command refuses these before any work."""
    known, pending = {}, {}
    for source, what in inputs:
        if source is None:
            continue
        try:
            st = os.stat(source)
            known.setdefault((st.st_dev, st.st_ino), (source, what))
        except (OSError, ValueError):
            pending.setdefault(os.path.realpath(source), (source, what))
    found = []
    for output in outputs:
        if output is None:
            continue
        try:
            st = os.stat(output)
            hit = known.get((st.st_dev, st.st_ino))
        except (OSError, ValueError):
            hit = pending.get(os.path.realpath(output)) if pending else None
        if hit:
            found.append((output, f"is {hit[0]}, {hit[1]}"))
    return found


def write_text(path, text: str) -> None:
    """`path`'s whole text, through `replaced`."""
    with replaced(path) as tmp:
        tmp.write_text(text)


def holds_text(path, text: str) -> bool:
    """Whether `path` is a regular file (not a link, FIFO or device) whose text is `text`."""
    path = Path(path)
    try:
        return stat.S_ISREG(os.lstat(path).st_mode) and path.read_text() == text
    except (OSError, UnicodeDecodeError):
        return False
