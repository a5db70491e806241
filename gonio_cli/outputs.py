"""Outputs as one transaction per command: staged, checked, then moved into place together.

Every command that writes files runs inside one :class:`Transaction` (opened by
:func:`gonio_cli.cli.run` around the command). Inside it:

* :func:`declare` is called by the command before any work: it refuses, in one line
  naming the option and the file, two outputs that are the same file, an output that is
  the same file as an input (symbolic links resolved, hard links found by
  :func:`os.path.samefile`), and an output that exists but is not a regular file (a
  device, a FIFO, a socket, a folder) or is read-only. It also removes temporary files
  left in the output folders by gonio runs that were killed (:func:`clean_stale`).
* :func:`gonio_cli.artifact.atomic_path` writes each file to a temporary file beside it
  (:data:`TMP_PREFIX`) and, for an output :func:`declare` named, *stages* it instead of
  moving it: the moves happen in :meth:`Transaction.commit`, after the command has
  finished, with Ctrl-C held back for the few renames. A failure or an interrupt before
  that point removes every staged file: the set of outputs is complete or absent, never
  partial. Files the command did not declare (caches, intermediate files it reads back)
  are moved into place at once, as outside a transaction.
* A folder output (``gonio report``, ``gonio prefilter``) is staged as a whole with
  :meth:`Transaction.stage_folder` (:func:`folder_output`); files written inside a staged
  folder are written there directly.

The outputs' transaction lives here and not in :mod:`gonio_cli.artifact` because the CLI
opens it around every command, ``gonio --version`` included: this module imports only
the standard library, :mod:`gonio_cli.errors` and :mod:`gonio_cli.folders`.

Temporary names are ``.gonio-tmp-<pid>-<random>-<name>``: the pid says which process
owns the file, the name keeps the extension (writers choose the format by it). A later run
writing into the same folder removes those whose process is no longer alive. It never
removes one whose process is alive, however old the file: a long render stages its
outputs only at its end, and a pid test cannot mistake a live gonio for a dead one (a pid
reused by an unrelated process only keeps a dead file longer, which is harmless). A file
made on another machine sharing the folder (NFS) is judged by a pid of this machine: it
is removed only when it is also older than :data:`STALE_AGE_S`. A process ended by
SIGTERM or SIGKILL runs no clean-up of its own; its files wait for that later run.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import stat
from pathlib import Path
from typing import Iterable, Iterator, Mapping

from .errors import OutputError
from .folders import folder_error, make_folder

#: Prefix of every temporary file and folder gonio makes beside an output.
TMP_PREFIX = ".gonio-tmp-"

#: ``.gonio-tmp-<pid>-<random>-<name>`` (random: mkstemp's 8 characters).
_TMP_NAME = re.compile(re.escape(TMP_PREFIX) + r"(\d+)-([A-Za-z0-9_]+)-(.*)\Z", re.S)

#: Age beyond which a temporary file whose pid is not running here is removed even if
#: the folder is shared with other machines (a day: no gonio stage runs that long, and
#: a file of a live run on another machine is rewritten or moved long before).
STALE_AGE_S = 24 * 3600.0


def tmp_prefix() -> str:
    """Prefix of this process's temporary names: ``.gonio-tmp-<pid>-``."""
    return f"{TMP_PREFIX}{os.getpid()}-"


def tmp_suffix(name: str) -> str:
    """Suffix of a temporary name for ``name``: ``-<name>`` (keeps its extension)."""
    return f"-{name}"


def _pid_alive(pid: int) -> bool:
    """Is process ``pid`` running on this machine (of any user)?"""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by another user
        return True
    except OSError:
        return True  # unknown: keep the file
    return True


#: File system types another machine may write to at the same time (``/proc/mounts``):
#: NFS, SMB, FUSE mounts (sshfs, s3fs, …) and the parallel file systems of clusters, where
#: a ``gonio batch`` worker on another node has pids this machine does not see.
SHARED_FS_TYPES = ("nfs", "cifs", "smb", "fuse", "lustre", "gpfs", "beegfs", "ceph", "9p",
                   "virtiofs", "glusterfs", "panfs", "wekafs")


def _is_network_fs(folder: str) -> bool:
    """Is ``folder`` on NFS/CIFS (where another machine's pids are not ours)? Linux only."""
    try:
        with open("/proc/self/mounts", encoding="utf-8") as fh:
            mounts = [line.split()[1:3] for line in fh if len(line.split()) > 2]
    except OSError:
        return False
    real = os.path.realpath(folder)
    best = max((m for m in mounts if real == m[0] or real.startswith(m[0].rstrip("/") + "/")),
               key=lambda m: len(m[0]), default=None)
    return best is not None and best[1].startswith(SHARED_FS_TYPES)


#: Folders already cleaned by this process (a folder is listed once per run).
_cleaned: set[str] = set()


def clean_stale(folder: str | os.PathLike) -> list[str]:
    """Remove temporary files and folders left in ``folder`` by killed gonio processes.

    A ``.gonio-tmp-<pid>-…`` entry is removed when its pid is not alive, and, on a network
    file system, only when it is also older than :data:`STALE_AGE_S`. Returns the names
    removed. Never raises (cleaning is a courtesy, not the command's job).
    """
    import shutil
    import time

    folder = os.fspath(folder) or "."
    key = os.path.abspath(folder)
    if key in _cleaned:
        return []
    _cleaned.add(key)
    try:
        names = [n for n in os.listdir(folder) if n.startswith(TMP_PREFIX)]
    except OSError:
        return []
    removed: list[str] = []
    network = None
    for name in names:
        m = _TMP_NAME.match(name)
        if m is None or int(m.group(1)) == os.getpid() or _pid_alive(int(m.group(1))):
            continue
        path = os.path.join(folder, name)
        try:
            st = os.lstat(path)
            if network is None:
                network = _is_network_fs(folder)
            if network and time.time() - st.st_mtime < STALE_AGE_S:
                continue
            if stat.S_ISDIR(st.st_mode):
                shutil.rmtree(path)
            else:
                os.unlink(path)
            removed.append(name)
        except OSError:
            continue
    return removed


# ------------------------------------------------------------------ the checks --

#: What ``stat`` calls a file that is not a regular file, for the message.
_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Do ``a`` and ``b`` name the same file: the same path after symbolic links, or, when
    both exist, the same inode (a hard link)?"""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return False


def _error(message: str, *, path=None, fix: str | None = None) -> OutputError:
    return OutputError(message, path=path, fix=fix)


def check_output(flag: str, path: str | os.PathLike, *, folder: bool = False) -> None:
    """Refuse an output that exists but cannot simply be replaced by a regular file.

    ``folder``: the output is a folder (``gonio report -o DIR``), so an existing folder is
    fine and an existing file is not.
    """
    path = os.fspath(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return  # absent: fine (a dangling link is replaced by the file)
    except NotADirectoryError as exc:  # a file where a folder of the path should be
        raise folder_error(os.path.dirname(path), exc) from None
    except OSError as exc:
        raise _error(f"{flag} {path}: cannot be examined ({exc.strerror})",
                     fix=f"choose another {flag}") from None
    if folder:
        if not stat.S_ISDIR(st.st_mode):
            raise _error(f"{flag} {path} exists and is not a folder", fix="name a folder")
        if not os.access(path, os.W_OK | os.X_OK):
            raise _error(f"{flag} {path} is a read-only folder", fix=f"choose another {flag}")
        return
    if stat.S_ISDIR(st.st_mode):
        raise _error("is a folder", path=path, fix="give a file name for the output")
    for test, kind in _KINDS:
        if test(st.st_mode):
            raise _error(f"{flag} {path} is {kind}, not a regular file",
                         fix=f"choose another {flag}: gonio writes regular files only")
    # root passes os.access on any file: a file without any write bit is read-only too
    if not (st.st_mode & 0o222) or not os.access(path, os.W_OK):
        raise _error(f"{flag} {path} is read-only", fix=f"choose another {flag}, or make "
                     "it writable (chmod u+w) if it may be replaced")


def check_distinct(outputs: Mapping[str, str | os.PathLike | None],
                   inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """Refuse two outputs that are the same file, or an output that is an input."""
    given = [(flag, p) for flag, p in outputs.items() if p is not None]
    for k, (flag, path) in enumerate(given):
        for other_flag, other in given[:k]:
            if same_file(path, other):
                raise _error(f"{flag} {path} is the same file as {other_flag} {other}",
                             fix=f"choose another {flag}")
        for src in inputs:
            if src is not None and same_file(path, src):
                raise _error(f"{flag} {path} is the input {src}: it would be overwritten",
                             fix=f"choose another {flag}")


def check_not_inside(flag: str, folder: str | os.PathLike,
                     inputs: Iterable[str | os.PathLike]) -> None:
    """Refuse a folder output that is replaced as a whole while it holds an input."""
    root = os.path.realpath(folder)
    for src in inputs:
        if os.path.realpath(src).startswith(root.rstrip(os.sep) + os.sep):
            raise _error(f"{flag} {folder} holds the input {src}, which replacing the "
                         "folder would delete", fix=f"choose another {flag}")


def declare(outputs: Mapping[str, str | os.PathLike | None],
            inputs: Iterable[str | os.PathLike | None] = (), *,
            folders: Iterable[str] = (), replaced: Iterable[str] = ()) -> None:
    """Check a command's outputs before any work (see the module docstring).

    Parameters
    ----------
    outputs : {flag: path or None}
        Every output the command may write, by the option that names it (``-o``,
        ``--report``); None for an option not given.
    inputs : paths
        Every file the command reads; an output may be none of them.
    folders : flags
        The outputs that are folders.
    replaced : flags
        The folder outputs replaced as a whole (``gonio report -o DIR``): none of the
        inputs may be inside them.

    Raises
    ------
    OutputError
        One line naming the option, the file and the fix.
    """
    replaced = set(replaced)
    folders = set(folders) | replaced
    inputs = [p for p in inputs if p is not None]
    for flag, path in outputs.items():
        if path is not None:
            check_output(flag, path, folder=flag in folders)
            if flag in replaced:
                check_not_inside(flag, path, inputs)
    check_distinct(outputs, inputs)
    tx = current()
    for path in outputs.values():
        if path is not None:
            if tx is not None:
                tx.outputs.add(_key(path))
            parent = os.path.dirname(os.path.abspath(path))
            if os.path.isdir(parent):
                clean_stale(parent)


# ------------------------------------------------------------------ the transaction --

@contextlib.contextmanager
def folder_output(final: str | os.PathLike, *, merge: bool = False) -> Iterator[Path]:
    """A temporary folder to fill; it becomes ``final`` when the command's transaction
    commits (or at the end of the block, outside a transaction). See
    :meth:`Transaction.stage_folder` for ``merge``."""
    tx = current()
    if tx is not None:
        yield tx.stage_folder(final, merge=merge)
        return
    with transaction() as tx:
        yield tx.stage_folder(final, merge=merge)
        tx.commit()


#: Files this process has moved into place, for the interrupt message.
_written: list[Path] = []


def note_written(path: str | os.PathLike) -> None:
    """Record that ``path`` is complete and in place."""
    _written.append(Path(path))


def written_files() -> list[Path]:
    """Files written by this process so far (in order; see :func:`forget_written`)."""
    return list(_written)


def forget_written() -> None:
    """Start a new record of written files (the CLI does so at the start of a run)."""
    _written.clear()


def readable(path: str | os.PathLike) -> Path:
    """Where the content of ``path`` is now: the staged temporary file while this
    command's transaction holds the output back, else ``path`` itself. For a command that
    reads back an output it wrote (the turntable's preview is made from its frames)."""
    tx = current()
    if tx is not None:
        key = _key(path)
        for tmp, final in tx.files:
            if _key(final) == key:
                return tmp
    return Path(path)


def _key(path: str | os.PathLike) -> str:
    """A path as the transaction compares them: its folder's links resolved."""
    path = os.fspath(path)
    return os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(path))),
                        os.path.basename(path))


class Transaction:
    """The outputs of one command: staged temporary files moved into place together.

    Only the files :func:`declare` named are staged; anything else the command writes
    (a cache, an intermediate file it reads back) is moved into place at once.
    """

    def __init__(self) -> None:
        self.outputs: set[str] = set()                # declared outputs (:func:`_key`)
        self.files: list[tuple[Path, Path]] = []      # (staged temporary, final path)
        self.folders: list[tuple[Path, Path, bool]] = []  # (staged folder, final, merge)
        self.done = False

    # -- staging --
    def stage(self, tmp: Path, final: Path) -> None:
        """Move the complete file ``tmp`` onto ``final`` at :meth:`commit` (a later stage
        of the same path replaces the earlier one)."""
        for k, (old_tmp, old_final) in enumerate(self.files):
            if same_file(old_final, final):
                old_tmp.unlink(missing_ok=True)
                self.files[k] = (tmp, final)
                return
        self.files.append((tmp, final))

    def stage_folder(self, final: str | os.PathLike, *, merge: bool = False) -> Path:
        """A new temporary folder beside ``final`` that replaces it at :meth:`commit`.

        ``merge``: move its files into an existing ``final`` (other files there stay)
        instead of replacing the folder as a whole.
        """
        import tempfile

        final = Path(final)
        parent = make_folder(final.parent if str(final.parent) else ".")
        clean_stale(parent)
        try:
            tmp = Path(tempfile.mkdtemp(prefix=tmp_prefix(), suffix=tmp_suffix(final.name),
                                        dir=parent))
        except OSError as exc:
            raise folder_error(parent, exc) from None
        self.folders.append((tmp, final, merge))
        return tmp

    def is_output(self, path: str | os.PathLike) -> bool:
        """Is ``path`` one of the declared outputs (so staged, not moved at once)?"""
        return _key(path) in self.outputs

    def inside_staged_folder(self, path: str | os.PathLike) -> bool:
        """Is ``path`` inside a folder this transaction staged (so written directly)?"""
        full = os.path.abspath(path)
        return any(full.startswith(os.path.abspath(tmp) + os.sep) for tmp, _, _ in self.folders)

    # -- ending --
    def abort(self) -> None:
        """Remove everything staged; nothing reaches its final path."""
        import shutil

        for tmp, _ in self.files:
            with contextlib.suppress(OSError):
                tmp.unlink()
        for tmp, _, _ in self.folders:
            shutil.rmtree(tmp, ignore_errors=True)
        self.files.clear()
        self.folders.clear()
        self.done = True

    def commit(self) -> None:
        """Move every staged output into place, Ctrl-C held back until the moves are done.

        The moves are renames within each output's folder (microseconds each); should one
        fail, the outputs already moved by this commit are removed again, so the set is
        absent rather than partial.
        """
        import shutil
        import signal
        import threading

        masked = threading.current_thread() is threading.main_thread() and hasattr(
            signal, "pthread_sigmask")
        hold = {signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM)}
        old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, hold) if masked else None
        moved: list[Path] = []
        try:
            for tmp, final in self.files:
                os.replace(tmp, final)
                moved.append(final)
            for tmp, final, merge in self.folders:
                self._move_folder(tmp, final, merge, moved)
            for path in moved:  # before Ctrl-C is let through, so its message is right
                note_written(path)
        except BaseException:
            for path in moved:
                with contextlib.suppress(OSError):
                    shutil.rmtree(path) if path.is_dir() and not path.is_symlink() \
                        else path.unlink()
            self.abort()
            raise
        finally:
            if masked:
                signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        self.files.clear()
        self.folders.clear()
        self.done = True

    @staticmethod
    def _move_folder(tmp: Path, final: Path, merge: bool, moved: list[Path]) -> None:
        import shutil

        os.chmod(tmp, 0o777 & ~umask())
        if not final.exists():
            os.replace(tmp, final)
            moved.append(final)
            return
        if merge:  # files one by one, index-like files (written last) last
            names = sorted(os.listdir(tmp), key=lambda n: (n.endswith(".json"), n))
            for name in names:
                os.replace(tmp / name, final / name)
                moved.append(final / name)
            os.rmdir(tmp)
            return
        old = final.parent / f"{tmp_prefix()}old-{final.name}"
        os.replace(final, old)
        os.replace(tmp, final)
        moved.append(final)
        shutil.rmtree(old, ignore_errors=True)


def umask() -> int:
    """The process umask (read by setting and restoring it): staged files and folders get
    the permissions a plain ``open``/``mkdir`` would give them."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: The transaction of the command running now (None outside :func:`transaction`); a
#: context variable, so commands run in threads each see their own.
_current: contextvars.ContextVar[Transaction | None] = contextvars.ContextVar(
    "gonio_outputs_transaction", default=None)


def current() -> Transaction | None:
    """The open transaction, if a command is running inside one."""
    return _current.get()


@contextlib.contextmanager
def transaction() -> Iterator[Transaction]:
    """Open the outputs' transaction; leaving it without :meth:`Transaction.commit`
    (an error, Ctrl-C, a non-zero exit) removes everything staged."""
    tx = Transaction()
    token = _current.set(tx)
    try:
        yield tx
    finally:
        _current.reset(token)
        if not tx.done:
            tx.abort()
