"""Atomic, symlink-safe file writing: every file driveid writes goes through here.

Rules (issue 12)
----------------
* A file is written under a temporary name created *exclusively* (``O_CREAT | O_EXCL``,
  which never follows a symbolic link) in the destination's own folder, and renamed onto
  the destination only once it is complete: an interrupted write (Ctrl-C, a full disk, an
  exception in the writer) leaves the destination as it was and no temporary file.
* A symbolic link at the destination is never followed: without ``overwrite`` it counts as
  an existing file (a dangling link too) and the write is refused; with ``overwrite`` the
  rename replaces the *link*, never the file it points to.
* A device, pipe or socket at the destination is never replaced, ``overwrite`` or not
  (the rename would replace the node itself: ``/dev/full`` as root, issue 28).
* Without ``overwrite`` the final step is ``os.link`` (fails if the name appeared
  meanwhile), so a file created by someone else between the check and the rename is not
  lost either.
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from driveid.errors import OverwriteError

__all__ = ["check_destination", "atomic_open", "atomic_write_text", "atomic_write_bytes",
           "atomic_save", "TEMP_SUFFIX"]

#: Suffix of the temporary files (before the destination's own suffix), e.g.
#: ``.run-001.csv.k3j2.part.csv``; a leftover one (only after a power cut or SIGKILL) can be
#: deleted.
TEMP_SUFFIX = ".part"


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def check_destination(path: str | Path, *, overwrite: bool = False,
                      option: str = "--overwrite") -> Path:
    """Check that writing ``path`` loses nothing, without following a symbolic link.

    Parameters
    ----------
    path : str or Path
        Destination file.
    overwrite : bool
        Allow replacing an existing file or symbolic link (the link itself is replaced).
    option : str
        Name of the command-line flag that allows overwriting, used in the message.

    Returns
    -------
    Path
        The destination (its folder is not created here).

    Raises
    ------
    OverwriteError
        If something exists at ``path`` (a file, a link, a dangling link) and ``overwrite``
        is False; if ``path`` is a device, pipe or socket (never replaced), or ``"-"``.
    IsADirectoryError
        If ``path`` is a folder (a real one; a link to a folder is replaced under
        ``overwrite``), or its spelling ends in ``/``.
    """
    text = os.fspath(path)
    if text == "-":
        raise OverwriteError(
            "'-' names no file here (driveid does not write this output to standard "
            "output); give a file name such as out.html")
    if text.endswith(("/", os.sep)) and not Path(text).is_dir():
        raise IsADirectoryError(
            f"{text} ends in '/', so it names a folder; give a file name without the "
            "trailing slash")
    path = Path(path)
    if path.is_dir() and not path.is_symlink():
        raise IsADirectoryError(
            f"{path} is a folder; give a file name (e.g. {path / 'out.csv'})")
    if (os.path.lexists(path) and not path.is_symlink()
            and not stat.S_ISREG(os.lstat(path).st_mode)):
        # a device, pipe or socket: the rename would replace the node itself (/dev/null,
        # /dev/full as root, found by the fifth hostile campaign), whatever --overwrite says
        raise OverwriteError(
            f"{path} is not a regular file (a device, pipe or socket); driveid writes "
            "regular files only: choose another name")
    if os.path.lexists(path) and not overwrite:
        link = path.is_symlink()
        raise OverwriteError(
            f"{path} exists ({'a symbolic link' if link else 'a file'}); choose another "
            f"name, or pass overwrite=True (CLI: {option}) to replace it"
            f"{' (the link, not its target)' if link else ''}"
        )
    return path


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, overwrite: bool = False,
                encoding: str | None = "utf-8", newline: str | None = None,
                option: str = "--overwrite") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success rename it onto ``path``.

    Parameters
    ----------
    path : str or Path
        Destination file; its folder is created if missing.
    mode : {"w", "wb"}
        Text or binary.
    overwrite : bool
        Replace an existing file or link (the link itself, not its target).
    encoding : str or None
        Text encoding (text mode only).
    newline : str or None
        Newline translation (text mode only), as :func:`open`.
    option : str
        Command-line flag named in the refusal message.

    Yields
    ------
    file object
        Open on the temporary file.

    Raises
    ------
    OverwriteError
        If ``path`` exists (or appeared during the write) and ``overwrite`` is False.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_open(d / "a.txt") as fh:
    ...     _ = fh.write("hello")
    >>> (d / "a.txt").read_text(), sorted(p.name for p in d.iterdir())
    ('hello', ['a.txt'])
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb'; got {mode!r}")
    path = check_destination(path, overwrite=overwrite, option=option)
    folder = path.parent
    tmp: Path | None = None
    try:
        with _interrupts_held():
            try:
                folder.mkdir(parents=True, exist_ok=True)
                # mkstemp opens with O_CREAT | O_EXCL (and O_NOFOLLOW where available): a
                # planted symlink at the temporary name makes it pick another name, never
                # write through it
                fd, tmp_name = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.",
                                                suffix=TEMP_SUFFIX + path.suffix)
            except PermissionError:
                # the raw message named the hidden temporary file, not the user's path
                raise PermissionError(
                    f"cannot write {path}: the folder {folder.resolve()} is not writable; "
                    "choose another folder") from None
            tmp = Path(tmp_name)
        kwargs: dict[str, Any] = ({} if "b" in mode else
                                  {"encoding": encoding, "newline": newline})
        with os.fdopen(fd, mode, **kwargs) as fh:
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
            yield fh
            fh.flush()
        _commit(tmp, path, overwrite=overwrite, option=option)
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM while the temporary file is created and its name kept.

    A signal between ``mkstemp`` creating the file and the caller knowing its name would
    leave the file behind (seen on a loaded CI machine). Here the handlers only note a
    signal; it is raised again on leaving this block, where the clean-up already knows the
    name. A signal mask would not do: another thread (a BLAS pool, a test runner's) takes a
    process-directed signal, and Python runs the handler in the main thread at once.
    Outside the main thread nothing is held: Python raises signals in the main thread only.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []
    before = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) is not None:  # None: a handler not set from Python
            before[signum] = signal.signal(signum, lambda s, _frame: noted.append(s))
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
        for signum in noted[:1]:
            signal.raise_signal(signum)  # now to the restored handler


def _commit(tmp: Path, path: Path, *, overwrite: bool, option: str) -> None:
    if overwrite:
        os.replace(tmp, path)  # replaces a link at `path` itself, never its target
        return
    try:
        os.link(tmp, path, follow_symlinks=False)
    except FileExistsError:
        raise OverwriteError(
            f"{path} appeared while it was being written; nothing was replaced; choose "
            f"another name or pass {option}") from None
    except OSError:  # a file system without hard links: re-check, then rename
        check_destination(path, overwrite=False, option=option)
        os.replace(tmp, path)
        return
    tmp.unlink()


def atomic_write_text(path: str | Path, text: str, *, overwrite: bool = False,
                      option: str = "--overwrite") -> Path:
    """Write text (UTF-8) atomically; see :func:`atomic_open`.

    Parameters
    ----------
    path : str or Path
        Destination file.
    text : str
        Content.
    overwrite : bool
        Replace an existing file or link.
    option : str
        Command-line flag named in the refusal message.

    Returns
    -------
    Path
        The written file.
    """
    with atomic_open(path, "w", overwrite=overwrite, option=option, newline="\n") as fh:
        fh.write(text)
    return Path(path)


def atomic_write_bytes(path: str | Path, data: bytes, *, overwrite: bool = False,
                       option: str = "--overwrite") -> Path:
    """Write bytes atomically; see :func:`atomic_open`.

    Parameters
    ----------
    path : str or Path
        Destination file.
    data : bytes
        Content.
    overwrite : bool
        Replace an existing file or link.
    option : str
        Command-line flag named in the refusal message.

    Returns
    -------
    Path
        The written file.
    """
    with atomic_open(path, "wb", overwrite=overwrite, option=option) as fh:
        fh.write(data)
    return Path(path)


def atomic_save(path: str | Path, writer: Callable[[IO[bytes]], Any], *,
                overwrite: bool = False, option: str = "--overwrite") -> Path:
    """Call ``writer(binary_file)`` on a temporary file, then move it onto ``path``.

    For writers that take an open file (``np.savez``, ``scipy.io.savemat``,
    ``Figure.savefig(fh, format=...)``).

    Parameters
    ----------
    path : str or Path
        Destination file.
    writer : callable
        Writes the content to the binary file object it is given.
    overwrite : bool
        Replace an existing file or link.
    option : str
        Command-line flag named in the refusal message.

    Returns
    -------
    Path
        The written file.
    """
    with atomic_open(path, "wb", overwrite=overwrite, option=option) as fh:
        writer(fh)
    return Path(path)
