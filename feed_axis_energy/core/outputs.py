"""Every file and directory the tool writes goes through here.

Rules (README, "Output files"):

* A name given for a place *inside* a requested directory (a run name, ``--manifest-name``)
  is one plain path component: not empty, not ``.`` or ``..``, no separator, no control
  character, at most 255 bytes, not a reserved name of that directory. It is confined to
  the directory after normalisation.
* An existing target is refused unless the caller passes ``force`` (the commands' ``--force``);
  a symbolic link as the target, even a dangling one, is always refused (never written through),
  and so is a parent directory that is not a real directory.
* Files are written to a hidden temporary sibling (``.<name>.tmp-<pid>``, created with
  ``O_EXCL | O_NOFOLLOW``), flushed to disk, then renamed into place; directories are built
  in a hidden temporary sibling directory and renamed into place when complete. On any
  exception, including the ``SystemExit`` that :func:`terminate_on_signals` raises for
  SIGTERM, and ``KeyboardInterrupt`` for SIGINT, the temporary is removed: nothing is left.
* SIGKILL cannot be caught: it may leave a hidden ``.<name>.tmp-<pid>`` beside the target,
  never the target itself. A rerun removes such temporaries of processes that no longer
  exist (:func:`remove_stale_temporaries`) and is not blocked by them.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import os
from pathlib import Path
import re
import shutil
import signal
import stat
import threading

from .errors import FeedAxisError

__all__ = ['OutputError', 'check_component', 'confined', 'check_target', 'write_text_atomic',
           'staged_directory', 'remove_stale_temporaries', 'terminate_on_signals']

_TMP_RE = re.compile(r'^\.(?P<name>.+)\.tmp-(?P<pid>[0-9]+)(?:-[0-9]+)?$')
_MAX_NAME_BYTES = 255
_SHOWN = 60


class OutputError(FeedAxisError):
    """An output that must not be written: names the option and the path."""

    def __init__(self, message: str, *, path: str | os.PathLike[str] = '', option: str = ''):
        self.path = _short(str(path))
        self.option = option
        self.reason = message
        where = ', '.join(p for p in (option, self.path) if p)
        super().__init__(f'{where}: {message}' if where else message)


def _short(text: str) -> str:
    """``text`` cut to a bounded length for messages."""
    text = text.encode('unicode_escape', 'backslashreplace').decode('ascii')
    return text if len(text) <= _SHOWN else text[:_SHOWN - 3] + '...'


def check_component(name: str, *, option: str, reserved: tuple[str, ...] = ()) -> str:
    """Return ``name`` if it is one safe path component, else raise :class:`OutputError`.

    Parameters
    ----------
    name
        The name as given (a run name, a file name inside an output directory).
    option
        The argument or key the name comes from, for the message.
    reserved
        Names of the directory that must not be used (compared case-insensitively).

    Returns
    -------
    str
        ``name`` unchanged.
    """
    shown = _short(name)
    if not isinstance(name, str) or not name.strip():
        raise OutputError('an empty name is not a file name', option=option)
    if name in ('.', '..'):
        raise OutputError(f'{shown!r} is not a file name', option=option)
    if '/' in name or '\\' in name or (os.altsep and os.altsep in name):
        raise OutputError(f'{shown!r} must be a plain name without a directory part',
                          option=option)
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise OutputError(f'{shown!r} contains a control character', option=option)
    if len(name.encode('utf-8', 'surrogatepass')) > _MAX_NAME_BYTES:
        raise OutputError(f'{shown!r} is longer than {_MAX_NAME_BYTES} bytes', option=option)
    if _TMP_RE.match(name):
        raise OutputError(f'{shown!r} looks like one of our temporary names', option=option)
    if name.casefold() in {r.casefold() for r in reserved}:
        raise OutputError(f'{shown!r} is reserved in this directory', option=option)
    return name


def confined(directory: str | os.PathLike[str], name: str, *, option: str,
             reserved: tuple[str, ...] = ()) -> Path:
    """``directory / name`` for a safe ``name`` (see :func:`check_component`).

    The result is checked again after normalisation to lie directly inside ``directory``.
    """
    check_component(name, option=option, reserved=reserved)
    base = Path(os.path.abspath(directory))
    path = Path(os.path.normpath(base / name))
    if path.parent != base:
        raise OutputError(f'{_short(name)!r} leaves the output directory', option=option)
    return Path(directory) / name


def _lexists(path: Path) -> os.stat_result | None:
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None


def check_target(path: str | os.PathLike[str], *, option: str, force: bool = False,
                 kind: str = 'file') -> Path:
    """Refuse a target that must not be (over)written; returns it as a :class:`Path`.

    Parameters
    ----------
    path
        The file or directory to create.
    option
        The argument it comes from, for messages.
    force
        Allow replacing an existing target of the same kind (never a symbolic link).
    kind
        ``'file'`` or ``'directory'``.

    Raises
    ------
    OutputError
        The target is a symbolic link (even dangling), exists without ``force``, exists as
        the other kind, or its parent exists but is not a directory (or is a link).
    """
    path = Path(path)
    st = _lexists(path)
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise OutputError('is a symbolic link; links are never written through',
                              path=path, option=option)
        if not force:
            raise OutputError('exists already; choose a new name or pass --force',
                              path=path, option=option)
        is_dir = stat.S_ISDIR(st.st_mode)
        if is_dir != (kind == 'directory'):
            other = 'a directory' if is_dir else 'not a directory'
            raise OutputError(f'exists and is {other}; not replaced', path=path,
                              option=option)
    parent = path.parent
    pst = _lexists(parent)
    if pst is not None and not stat.S_ISDIR(pst.st_mode):
        what = 'a symbolic link' if stat.S_ISLNK(pst.st_mode) else 'not a directory'
        raise OutputError(f'its parent {_short(str(parent))} is {what}', path=path,
                          option=option)
    return path


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temporaries(path: str | os.PathLike[str]) -> int:
    """Remove ``.<name>.tmp-<pid>`` siblings of ``path`` left by processes that are gone.

    Returns the number removed. Temporaries of running processes are left alone.
    """
    path = Path(path)
    parent = path.parent
    removed = 0
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return 0
    for entry in entries:
        m = _TMP_RE.match(entry.name)
        if m is None or m.group('name') != path.name:
            continue
        if _pid_alive(int(m.group('pid'))):
            continue
        _remove(Path(entry.path))
        removed += 1
    return removed


def _remove(path: Path) -> None:
    """Remove a file, link or directory tree without following links."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISDIR(st.st_mode):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def _tmp_name(path: Path) -> Path:
    return path.with_name(f'.{path.name}.tmp-{os.getpid()}')


def _make_parent(path: Path, option: str) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError as err:
        raise OutputError(f'cannot create its directory: {err.strerror}', path=path,
                          option=option) from err


def write_text_atomic(path: str | os.PathLike[str], text: str, *, option: str,
                      force: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary sibling and a rename.

    Without ``force`` the final step is a hard link, which fails if the target appeared in
    the meantime, so an existing file is never replaced. Returns ``path``.
    """
    path = check_target(path, option=option, force=force, kind='file')
    _make_parent(path, option)
    remove_stale_temporaries(path)
    tmp = _tmp_name(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
    fd = os.open(tmp, flags, 0o644)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        check_target(path, option=option, force=force, kind='file')
        if force:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path, follow_symlinks=False)
            except FileExistsError as err:
                raise OutputError('appeared while writing; not replaced', path=path,
                                  option=option) from err
            os.unlink(tmp)
    except BaseException:
        _remove(tmp)
        raise
    return path


@contextlib.contextmanager
def staged_directory(path: str | os.PathLike[str], *, option: str,
                     force: bool = False) -> Iterator[Path]:
    """Build a directory output in a temporary place, renamed to ``path`` when complete.

    Yields ``.<name>.tmp-<pid>/<name>``, a path that does not exist yet, inside a hidden
    temporary sibling directory: the caller creates it (a rosbags writer creates its bag
    directory itself and names its files after it, so the name is kept). When the block
    ends without an exception it is renamed to ``path``; on any exception the temporary is
    removed and nothing of the output exists. With ``force`` an existing directory is
    replaced only after the new one is complete.
    """
    path = check_target(path, option=option, force=force, kind='directory')
    _make_parent(path, option)
    remove_stale_temporaries(path)
    tmp = _tmp_name(path)
    os.mkdir(tmp, 0o700)
    old: Path | None = None
    try:
        inner = tmp / path.name
        yield inner
        if _lexists(inner) is None:
            os.mkdir(inner, 0o755)
        check_target(path, option=option, force=force, kind='directory')
        if _lexists(path) is not None:
            old = path.with_name(f'.{path.name}.tmp-{os.getpid()}-1')
            os.rename(path, old)
        os.rename(inner, path)
    except BaseException:
        if old is not None and _lexists(path) is None:
            os.rename(old, path)
            old = None
        raise
    finally:
        _remove(tmp)
        if old is not None:
            _remove(old)


class _Terminated(SystemExit):
    """Raised in the main thread on SIGTERM so that cleanup code runs."""


@contextlib.contextmanager
def terminate_on_signals() -> Iterator[None]:
    """Turn SIGTERM into a ``SystemExit(143)`` (SIGINT already raises KeyboardInterrupt).

    ``finally`` blocks and the staged outputs above then remove their temporaries. The
    previous handler is restored on exit. Only in the main thread (signals are delivered
    there); elsewhere a no-op.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise _Terminated(128 + signum)

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
