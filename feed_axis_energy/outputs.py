"""Every file and directory the tool writes goes through here.

Rules (README, "Output files"):

* A name given for a place *inside* a requested directory (a run name, ``--manifest-name``)
  is one plain path component: not empty, not ``.`` or ``..``, no separator, no control
  character, at most 255 bytes, not a reserved name of that directory. It is confined to
  the directory after normalisation.
* An existing target is refused unless the caller passes ``force`` (the commands' ``--force``);
  with ``force`` a directory is replaced only if the command recognises it as its own earlier
  output (``replaceable``). A symbolic link as the target, even a dangling one, is always
  refused (never written through), and so is a parent that is not a directory.
* Files are written to a hidden temporary sibling (``.<name>.tmp-<pid>``, created with
  ``O_EXCL | O_NOFOLLOW``), flushed to disk, then renamed into place; directories are built
  in a hidden temporary sibling directory and renamed into place when complete. On any
  exception, including the :class:`Terminated` that :func:`terminate_on_signals` raises for
  SIGTERM and SIGINT, the temporary is removed: nothing is left.
* SIGKILL cannot be caught: it may leave a hidden ``.<name>.tmp-<pid>`` beside the target,
  never a partial target (in the instant of a ``force`` swap: the earlier output as
  ``.<name>.tmp-<pid>-1``). The next write of the same target removes such temporaries of
  processes that no longer exist (:func:`remove_stale_temporaries`) and is not blocked by them.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import os
from pathlib import Path
import re
import shutil
import stat
from typing import NoReturn

from .errors import OutputError, shorten, shorten_path

__all__ = ['check_component', 'confined', 'check_target', 'write_text_atomic', 'staged_directory',
           'remove_stale_temporaries', 'marked_or_empty', 'is_bag_directory', 'Rollback',
           'REPORT_MARKER']

_TMP_RE = re.compile(r'^\.(?P<name>.+)\.tmp-(?P<pid>[0-9]{1,10})(?:-(?P<n>[0-9]{1,6}))?$')
REPORT_MARKER = '.feed_axis_energy_report'
"""File in a report directory (compare/analyze ``--report``): ``--force`` may replace it."""
_MAX_NAME_BYTES = 255
_PID_MAX = 1 << 22      # Linux's largest pid_max; anything above is no pid of ours


def _short_name(text: str) -> str:
    """A name for messages: control characters escaped, cut to a bounded length."""
    return shorten(text.encode('unicode_escape', 'backslashreplace').decode('ascii'))


def check_component(name: str, *, option: str, reserved: tuple[str, ...] = (),
                    why: str = 'reserved in this directory') -> str:
    """Return ``name`` if it is one safe path component, else raise :class:`OutputError`.

    Parameters
    ----------
    name
        The name as given (a run name, a file name inside an output directory).
    option
        The argument or key the name comes from, for the message.
    reserved
        Names of the directory that must not be used (compared case-insensitively, so that
        a case-insensitive file system cannot make two outputs one).
    why
        Why the reserved names are, for the message.

    Returns
    -------
    str
        ``name`` unchanged.

    Raises
    ------
    OutputError
        Empty, ``.``/``..``, a separator, a control character, over 255 bytes (UTF-8), the
        form of our temporary names, or a reserved name.
    """
    if not isinstance(name, str):
        raise OutputError(f'expected a file name, got a value of type {type(name).__name__}',
                          option=option)
    shown = _short_name(name)
    if not name.strip():
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
        raise OutputError(f'{shown!r} has the form of a temporary name', option=option)
    if name.casefold() in {r.casefold() for r in reserved}:
        raise OutputError(f'{shown!r} is {why}', option=option)
    return name


def confined(directory: str | os.PathLike[str], name: str, *, option: str,
             reserved: tuple[str, ...] = (), why: str = 'reserved in this directory') -> Path:
    """``directory / name`` for a safe ``name`` (see :func:`check_component`).

    Checked again after normalisation to lie directly inside ``directory``.

    Parameters
    ----------
    directory
        The requested output directory.
    name
        One path component.
    option
        The argument or key ``name`` comes from.
    reserved, why
        Names that must not be used in ``directory``, and why (see :func:`check_component`).

    Returns
    -------
    pathlib.Path
        ``Path(directory) / name``.
    """
    check_component(name, option=option, reserved=reserved, why=why)
    base = Path(os.path.abspath(directory))
    path = Path(os.path.normpath(base / name))
    if path.parent != base:  # pragma: no cover - check_component already refuses this
        raise OutputError(f'{_short_name(name)!r} leaves the output directory', option=option)
    return Path(directory) / name


def _lstat(path: Path) -> os.stat_result | None:
    try:
        return os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None


def marked_or_empty(marker: str) -> Callable[[Path], bool]:
    """A ``replaceable`` test: an empty directory or one holding the file ``marker``."""
    def test(path: Path) -> bool:
        mst = _lstat(path / marker)
        if mst is not None and stat.S_ISREG(mst.st_mode):
            return True
        with os.scandir(path) as entries:
            return next(entries, None) is None
    return test


def is_bag_directory(path: Path) -> bool:
    """A ``replaceable`` test: a rosbag2 directory (``metadata.yaml`` and plain files only)."""
    names = []
    with os.scandir(path) as entries:
        for entry in entries:
            if not entry.is_file(follow_symlinks=False):
                return False
            names.append(entry.name)
    return not names or 'metadata.yaml' in names


def check_target(path: str | os.PathLike[str], *, option: str, force: bool = False,
                 kind: str = 'file', replaceable: Callable[[Path], bool] | None = None,
                 forceable: bool = True) -> Path:
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
    replaceable
        For directories with ``force``: a test that the existing directory is one the
        command may replace (its own earlier output); default: any directory.
    forceable
        Whether the command has a ``--force`` (only changes the message's advice).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        The target is a symbolic link (even dangling), exists without ``force``, exists as
        the other kind or fails ``replaceable``, or its parent exists but is not a directory.
    """
    if kind not in ('file', 'directory'):
        raise ValueError(f'kind must be file or directory, got {kind!r}')
    path = Path(path)
    st = _lstat(path)
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise OutputError('is a symbolic link; links are never written through',
                              path=path, option=option)
        if not force:
            advice = ' or pass --force' if forceable else ''
            raise OutputError(f'exists already; choose a new name{advice}',
                              path=path, option=option)
        is_dir = stat.S_ISDIR(st.st_mode)
        if is_dir != (kind == 'directory'):
            other = 'a directory' if is_dir else 'not a directory'
            raise OutputError(f'exists and is {other}; not replaced', path=path,
                              option=option)
        if is_dir and replaceable is not None and not replaceable(path):
            raise OutputError('exists and is not an earlier output of this command; '
                              'not replaced, even with --force', path=path, option=option)
    parent = path.parent
    # The parent may be a link to a directory (the user's choice of place); the target
    # itself is never a link.
    if parent.exists() and not parent.is_dir():
        raise OutputError(f'its parent {shorten_path(str(parent))} is not a directory', path=path,
                          option=option)
    if os.path.lexists(parent) and not parent.exists():
        raise OutputError(f'its parent {shorten_path(str(parent))} is a dangling symbolic link',
                          path=path, option=option)
    return path


def _pid_alive(pid: int) -> bool:
    if pid <= 0 or pid > _PID_MAX:
        return True     # not a pid: leave the entry alone
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_stale_temporaries(path: str | os.PathLike[str]) -> int:
    """Remove ``.<name>.tmp-<pid>`` siblings of ``path`` left by processes that are gone.

    A temporary named with this process's pid is stale too (its creator had this pid and is
    gone, or it is this process, which writes one target at a time).

    Parameters
    ----------
    path
        The target whose temporaries are looked for.

    Returns
    -------
    int
        The number removed. Temporaries of other running processes are left alone.
    """
    path = Path(path)
    removed = 0
    try:
        with os.scandir(path.parent) as it:
            entries = list(it)
    except OSError:
        return 0
    for entry in entries:
        m = _TMP_RE.match(entry.name)
        if m is None or m.group('name') != path.name:
            continue
        pid = int(m.group('pid'))
        if pid != os.getpid() and _pid_alive(pid):
            continue
        _remove(Path(entry.path))
        removed += 1
    return removed


def _remove(path: Path) -> None:
    """Remove a file, link or directory tree without following links."""
    st = _lstat(path)
    if st is None:
        return
    if stat.S_ISDIR(st.st_mode):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def _tmp_name(path: Path, n: int = 0) -> Path:
    suffix = f'-{n}' if n else ''
    return path.with_name(f'.{path.name}.tmp-{os.getpid()}{suffix}')


def _missing_parents(path: Path) -> list[Path]:
    """The parents of ``path`` that do not exist yet, deepest first."""
    missing = []
    here = Path(os.path.abspath(path)).parent
    while not os.path.lexists(here) and here.parent != here:
        missing.append(here)
        here = here.parent
    return missing


def _remove_empty(directories: list[Path]) -> None:
    """Remove directories (deepest first) that are empty; leave any other."""
    for directory in directories:
        with contextlib.suppress(OSError):
            os.rmdir(directory)


def _make_parent(path: Path, option: str) -> list[Path]:
    """Create the parents of ``path``; return those created (to remove them on failure)."""
    missing = _missing_parents(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        _remove_empty(missing)
        raise OutputError(f'cannot create its directory: {_reason(err)}', path=path,
                          option=option) from err
    return missing


def _reason(err: OSError) -> str:
    """The system's words for ``err``, without the (temporary) file name."""
    return shorten(err.strerror or str(err) or type(err).__name__)


def _reraise(err: BaseException, path: Path, option: str) -> NoReturn:
    """After cleanup, an OSError becomes an OutputError naming the argument, not the temporary."""
    if isinstance(err, OSError):
        raise OutputError(f'could not be written ({_reason(err)}); nothing was left',
                          path=path, option=option) from err
    raise err


def _sync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (best effort: not every system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY | getattr(os, 'O_DIRECTORY', 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, option: str,
                      force: bool = False, forceable: bool = True,
                      newline: str | None = None) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary sibling and a rename.

    Without ``force`` the final step is a hard link, which fails if the target appeared in
    the meantime, so an existing file is never replaced; with ``force`` it is
    :func:`os.replace`, which replaces a file (or a link put there meanwhile) and never
    writes through a link.

    Parameters
    ----------
    path
        The file to write.
    text
        Its content.
    option
        The argument it comes from, for messages.
    force
        Replace an existing file.
    forceable
        Whether the command has a ``--force`` (for the message).
    newline
        As for :func:`open`: ``''`` writes the line ends of ``text`` untranslated (CSV text
        that carries its own); default: ``'\\n'`` becomes :data:`os.linesep`.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = check_target(path, option=option, force=force, kind='file', forceable=forceable)
    created = _make_parent(path, option)
    remove_stale_temporaries(path)
    tmp = _tmp_name(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
    try:
        fd = os.open(tmp, flags, 0o644)
    except BaseException as err:
        _remove_empty(created)
        _reraise(err, path, option)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8', newline=newline) as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        check_target(path, option=option, force=force, kind='file', forceable=forceable)
        if force:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path, follow_symlinks=False)
            except FileExistsError as err:
                raise OutputError('appeared while writing; not replaced', path=path,
                                  option=option) from err
            os.unlink(tmp)
        _sync_directory(path.parent)
    except BaseException as err:
        _remove(tmp)
        _remove_empty(created)
        _reraise(err, path, option)
    return path


@contextlib.contextmanager
def staged_directory(path: str | os.PathLike[str], *, option: str, force: bool = False,
                     replaceable: Callable[[Path], bool] | None = None,
                     forceable: bool = True) -> Iterator[Path]:
    """Build a directory output in a temporary place, renamed to ``path`` when complete.

    Yields ``.<name>.tmp-<pid>/<name>``, a path that does not exist yet, inside a hidden
    temporary sibling directory: the caller creates it (a rosbags writer creates its bag
    directory itself and names its files after it, so the name is kept). When the block
    ends without an exception it is renamed to ``path``; on any exception the temporary is
    removed and nothing of the output exists. With ``force`` an existing directory that
    passes ``replaceable`` is replaced only after the new one is complete.

    Parameters
    ----------
    path
        The directory to create.
    option
        The argument it comes from, for messages.
    force
        Replace an existing directory (see :func:`check_target`).
    replaceable
        Which existing directories ``force`` may replace.
    forceable
        Whether the command has a ``--force`` (for the message).

    Yields
    ------
    pathlib.Path
        Where to build the directory.
    """
    path = check_target(path, option=option, force=force, kind='directory',
                        replaceable=replaceable, forceable=forceable)
    created = _make_parent(path, option)
    remove_stale_temporaries(path)
    tmp = _tmp_name(path)
    old: Path | None = None
    try:
        os.mkdir(tmp, 0o700)
        inner = tmp / path.name
        yield inner
        if _lstat(inner) is None:
            os.mkdir(inner, 0o755)
        check_target(path, option=option, force=force, kind='directory',
                     replaceable=replaceable, forceable=forceable)
        if _lstat(path) is not None:
            old = _tmp_name(path, 1)
            os.rename(path, old)
        os.rename(inner, path)
        _sync_directory(path.parent)
    except BaseException as err:
        if old is not None and _lstat(path) is None:
            os.rename(old, path)    # put the earlier output back
            old = None
        _remove(tmp)
        _remove_empty(created)
        _reraise(err, path, option)
    finally:
        _remove(tmp)
        if old is not None:
            _remove(old)


class Rollback:
    """Remove, on failure, every output one invocation has completed (context manager).

    ``add`` the paths as they are completed; when the block raises, they are removed in
    reverse order (links are not followed), and so are the directory given as ``created``
    and its parents if this invocation created them and they are empty again.

    Parameters
    ----------
    created
        A directory that the invocation may create with its parents (those missing now are
        recorded).
    """

    def __init__(self, created: str | os.PathLike[str] | None = None):
        self._paths: list[Path] = []
        self._missing: list[Path] = []
        if created is not None:
            self._missing = _missing_parents(Path(created) / 'x')

    def add(self, path: str | os.PathLike[str]) -> None:
        """Record a completed output."""
        self._paths.append(Path(path))

    def __enter__(self) -> 'Rollback':
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            return
        for path in reversed(self._paths):
            _remove(path)
        _remove_empty(self._missing)
