"""Write a file all at once or not at all.

Data goes to a hidden temporary file in the target directory
(``.<file name>.rls-<random>.tmp``, ``temporary_name``), which then
replaces the target (``os.replace``; without ``overwrite`` a hard link, which
fails if the target appeared meanwhile). Any exception, KeyboardInterrupt
included, removes the temporary file. OS failures become ``OutputError``. A process killed outright (SIGKILL, a lost node)
can still leave a temporary: ``stale_temporaries`` finds those of given files so a
later run can remove them.
"""

import errno
import os
import pathlib
import re
import tempfile

from ...errors import OutputError
from ...stop_signals import held


TEMPORARY_MARK = ".rls-"
TEMPORARY_SUFFIX = ".tmp"
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.rls-[A-Za-z0-9_]+\.tmp$")


def temporary_name(name, random):
    """The name of the temporary file a write of file ``name`` goes through."""
    return f".{name}{TEMPORARY_MARK}{random}{TEMPORARY_SUFFIX}"


def stale_temporaries(paths):
    """The temporary files (full paths) of writes of ``paths`` that did not end: one
    listing per folder, whatever the number of paths."""
    by_folder = {}
    for p in paths:
        p = os.path.abspath(os.fspath(p))
        by_folder.setdefault(os.path.dirname(p), set()).add(os.path.basename(p))
    found = []
    for folder, names in by_folder.items():
        try:
            entries = os.listdir(folder)
        except OSError:
            continue
        for entry in entries:
            m = _TEMPORARY.match(entry)
            if m and m.group("name") in names:
                found.append(os.path.join(folder, entry))
    return sorted(found)


def _oserror(path, exc, action="write"):
    if exc.errno == errno.ENOSPC:
        return OutputError(f"disk full while writing {path}: free some space or choose another output directory")
    if exc.errno == errno.EDQUOT:
        return OutputError(f"disk quota exceeded while writing {path}")
    reason = exc.strerror or str(exc)
    return OutputError(f"cannot {action} {path}: {reason}")


def _exists_error(path):
    return OutputError(f"{path} already exists; pass --overwrite to replace it")


def ensure_directory(directory):
    """Create ``directory`` and its parents; clear ``OutputError`` if impossible."""
    directory = pathlib.Path(directory)
    if directory.is_dir():
        return directory
    if directory.exists():  # makedirs would say only "File exists"
        raise OutputError(f"cannot create directory {directory}: a file is in the way")
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        raise _oserror(directory, exc, "create directory") from None
    if not directory.is_dir():
        raise OutputError(f"cannot create directory {directory}: a file is in the way")
    return directory


def writable_folder(path):
    """Create the output folder ``path`` if needed and make sure files can be written
    there; raise ``OutputError`` saying why not. Returns the path as given."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise OutputError(f"output folder {path} is a file, not a folder")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {path}: {exc.strerror}") from None
    if not os.access(path, os.W_OK):
        raise OutputError(f"output folder {path} is not writable")
    return path


def atomic_write_bytes(path, data, overwrite=False):
    """Write ``data`` (bytes-like, or a callable taking a binary file) to ``path``.

    Returns the path. Raises ``OutputError`` if the file exists and
    ``overwrite`` is false, or the directory cannot be created or written. A stop
    signal (SIGTERM, SIGHUP) waits for the write to end (``core.stop_signals.held``): one
    between creating the temporary and the line that cleans it up left it behind.
    """
    with held():
        return _atomic_write_bytes(path, data, overwrite)


def _atomic_write_bytes(path, data, overwrite):
    path = pathlib.Path(path)
    _check_target(path, overwrite)
    tmp = _temporary(path, data)
    try:
        _place(tmp, path, overwrite)
    except BaseException:
        _unlink_quietly(tmp)
        raise
    return path


def _check_target(path, overwrite):
    """Refuse a directory in the way, or an existing file without ``overwrite``."""
    if path.is_dir():
        raise OutputError(f"cannot write {path}: it is a directory")
    if path.exists() and not overwrite:
        raise _exists_error(path)


def _temporary(path, data):
    """The temporary of a write of ``path`` (beside it), holding ``data`` (bytes-like,
    or a callable taking a binary file), synced and readable by all; it is removed
    again if anything fails on the way."""
    ensure_directory(path.parent)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{TEMPORARY_MARK}",
                                   suffix=TEMPORARY_SUFFIX, dir=path.parent)
    except OSError as exc:
        raise _oserror(path, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; clouds are meant to be shared
    except BaseException as exc:
        _unlink_quietly(tmp)
        if isinstance(exc, OSError):
            raise _oserror(path, exc) from None
        raise
    return tmp


def place(tmp, path, overwrite):
    """The complete temporary ``tmp`` takes its name ``path`` (without ``overwrite``,
    never over a file that appeared meanwhile); ``OutputError`` otherwise."""
    _place(tmp, pathlib.Path(path), overwrite)


def _place(tmp, path, overwrite):
    try:
        if overwrite:
            os.replace(tmp, path)
        else:
            _link_no_clobber(tmp, path)
    except FileExistsError:
        raise _exists_error(path) from None
    except OSError as exc:
        raise _oserror(path, exc) from None


def _unlink_quietly(path):
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


def atomic_write_files(files, overwrite=False):
    """Write several files as one: ``files`` maps paths to bytes. Every file is first
    written to its temporary; only when all are complete do they take their names, so
    a failure (a full disk, an interrupt) leaves none of them, not a part of the set.
    Returns the paths in the order given."""
    with held():
        return _atomic_write_files(files, overwrite)


def _atomic_write_files(files, overwrite):
    paths = [pathlib.Path(p) for p in files]
    for path in paths:
        _check_target(path, overwrite)
    temporaries, placed = [], []
    try:
        for path, data in zip(paths, files.values()):
            temporaries.append(_temporary(path, data))
        for path, tmp in zip(paths, temporaries):
            _place(tmp, path, overwrite)
            placed.append(path)
    except BaseException:
        for tmp in temporaries:
            _unlink_quietly(tmp)
        if not overwrite:  # what this call placed did not exist before it
            for path in placed:
                _unlink_quietly(path)
        raise
    return paths


def _link_no_clobber(tmp, path):
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise
    except OSError:
        # file systems without hard links: check, then replace
        if path.exists():
            raise FileExistsError(errno.EEXIST, "exists", str(path)) from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def parts_writer(parts):
    """A writer of ``parts`` (buffers, one after another) for ``atomic_write_bytes``."""
    def write(fh):
        for part in parts:
            fh.write(part)
    return write
