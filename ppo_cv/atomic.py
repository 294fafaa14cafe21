"""All-or-nothing output: files and folders built beside their target and renamed into place.

A target that already exists is never touched unless ``overwrite`` is given; then it is replaced
only after the new content is complete. An exception, a KeyboardInterrupt or (after
:func:`sigterm_as_interrupt`) a SIGTERM removes the temporary sibling and leaves the target as
it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "check_target",
    "check_apart",
    "atomic_file",
    "atomic_directory",
    "signals_deferred",
    "sigterm_as_interrupt",
    "stop_listening",
    "worker_pool",
]


def check_target(
    path: str | os.PathLike,
    kind: str,
    overwrite: bool = False,
    inputs: Iterable[str | os.PathLike] = (),
    name: str = "",
) -> Path:
    """Check that ``path`` can receive a new file or folder; raise ValueError naming the problem.

    Parameters
    ----------
    path : path
        The output to create.
    kind : {"file", "folder"}
        What will be written there.
    overwrite : bool
        Allow replacing an existing output of the same kind.
    inputs : iterable of paths
        Files and folders the command reads, which the output must keep apart from
        (:func:`check_apart`), even with ``overwrite``.
    name : str
        How messages about ``inputs`` call the output, e.g. ``"--out "``.

    Returns
    -------
    pathlib.Path
        ``path``, its parent folder existing and writable.
    """
    target = Path(path)
    parent = target.parent
    for ancestor in (parent, *parent.parents):
        if ancestor.exists() and not ancestor.is_dir():
            raise ValueError(f"cannot write {target}: {ancestor} is a file, not a folder")
        if ancestor.exists():
            break
    if kind == "file":
        if target.is_dir() or str(path).endswith(os.sep):
            raise ValueError(f"{target} is a folder; give a file name")
        check_apart(target, inputs, name)
        if not parent.is_dir():
            raise ValueError(f"cannot write {target}: folder {parent} does not exist")
        if target.exists() and not overwrite:
            raise ValueError(f"{target} already exists; pass --overwrite to replace it")
        if target.exists() and not target.is_file():
            raise ValueError(f"{target} is not a regular file")
    else:
        check_apart(target, inputs, name)
        if target.exists() and not target.is_dir():
            raise ValueError(f"{target} is a file, not a folder")
        if target.is_dir() and any(target.iterdir()) and not overwrite:
            raise ValueError(
                f"{target} exists and is not an empty directory; pass --overwrite to replace it"
            )
    existing = next((p for p in (parent, *parent.parents) if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"cannot write {target}: {existing} is not writable")
    return target


def check_apart(
    target: str | os.PathLike, inputs: Iterable[str | os.PathLike], name: str = ""
) -> None:
    """ValueError unless the output ``target`` is apart from every one of ``inputs``.

    An output that is an input, or a folder that holds one, would replace or delete it (with
    ``overwrite``). Symbolic links and ``..`` are resolved first, and a second name of the same
    file (a hard link) counts as the same. An output inside an input folder is allowed: the
    commands read the images they are given, or an image folder's image files, never an
    output's folder or file.

    Parameters
    ----------
    target : path
        An output file or folder, existing or not.
    inputs : iterable of paths
        The files and folders the command reads.
    name : str
        How the message calls the output, e.g. ``"--out "``.
    """
    output = Path(os.path.realpath(target))
    for source in inputs:
        read = Path(os.path.realpath(source))
        same = read == output
        with contextlib.suppress(OSError):
            same = same or os.path.samefile(read, output)
        if same or read.is_relative_to(output):
            relation = "is the input" if same else "holds the input"
            raise ValueError(
                f"the output {name}{target} {relation} {source}; give an output apart from the "
                "inputs"
            )


_DEFERRED = {signal.SIGINT, signal.SIGTERM}
_held: int | None = None  # a signal that reached :func:`_raise_interrupt` in a deferred block
_depth = 0


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back until the block is over.

    Creating a temporary entry and entering the ``try`` that removes it, or swapping an output
    into place, must not be split by an interrupt; a signal that arrives meanwhile is delivered,
    and its KeyboardInterrupt raised, as soon as the block ends. The signals are blocked in this
    thread, and one that the kernel hands to another thread (numpy's and OpenCV's workers do not
    block it) is held by :func:`_raise_interrupt` until the block ends.
    """
    global _depth, _held
    handled_here = threading.current_thread() is threading.main_thread()  # as Python's handlers
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _DEFERRED)
    _depth += handled_here
    try:
        yield
    finally:
        _depth -= handled_here
        held = None
        if handled_here and _depth == 0:
            held, _held = _held, None
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
        if held is not None:
            raise KeyboardInterrupt(f"signal {held}")


@contextlib.contextmanager
def worker_pool(workers: int, initializer: Callable[[], None]) -> Iterator[Any]:
    """A ``multiprocessing`` pool of ``workers`` spawned processes, stopped on any error.

    The pool starts with SIGINT and SIGTERM deferred (:func:`signals_deferred`): an interrupt
    that lands while a worker is being launched would leave it reading its start-up data from
    a closed pipe, and dying of that with a traceback. ``initializer`` runs in each worker (a
    module-level function: it is pickled). On an exception or an interrupt in the block the
    workers are stopped and joined before it propagates: none is left writing into an output
    the caller then removes.
    """
    import multiprocessing

    pool = None
    try:
        with signals_deferred():
            pool = multiprocessing.get_context("spawn").Pool(workers, initializer=initializer)
        yield pool
    except BaseException:
        if pool is not None:
            pool.terminate()
            pool.join()
        raise
    pool.close()
    pool.join()


def _visible_mode(path: Path, base: int) -> None:
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, base & ~umask)  # mkstemp / mkdtemp create private entries


def _replace(staging: Path, target: Path, overwrite: bool) -> None:
    """Move ``staging`` onto ``target``; an existing target is set aside, then removed."""
    if not (target.exists() or target.is_symlink()):
        os.rename(staging, target)
        return
    if not overwrite and not (target.is_dir() and not any(target.iterdir())):
        raise ValueError(f"{target} already exists; pass --overwrite to replace it")
    if target.is_file() and staging.is_file():
        os.replace(staging, target)
        return
    aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.old.", dir=target.parent))
    os.rename(target, aside / "old")
    try:
        os.rename(staging, target)
    except BaseException:
        os.rename(aside / "old", target)
        raise
    finally:
        shutil.rmtree(aside, ignore_errors=True)


@contextlib.contextmanager
def atomic_file(
    path: str | os.PathLike, overwrite: bool = False, mode: str = "w"
) -> Iterator[object]:
    """Open a temporary sibling of ``path`` for writing; rename it to ``path`` on success.

    Yields the open file (text mode ``"w"`` in UTF-8, or ``"wb"``). On any exception, including
    KeyboardInterrupt, the temporary file is removed and ``path`` is left untouched.
    """
    target = check_target(path, "file", overwrite)
    staging = None
    try:
        with signals_deferred():
            descriptor, name = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
            staging = Path(name)
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(descriptor, mode, encoding=encoding) as handle:
            yield handle
        _visible_mode(staging, 0o666)
        with signals_deferred():
            _replace(staging, target, overwrite)
    except BaseException:
        if staging is not None:
            staging.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike, overwrite: bool = False) -> Iterator[Path]:
    """A temporary sibling folder of ``path``, renamed to ``path`` when the block succeeds.

    An empty existing folder is replaced; a non-empty one or a file only with ``overwrite``.
    On any exception the temporary folder is removed and ``path`` is left untouched.
    """
    target = check_target(path, "folder", overwrite)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = None
    try:
        with signals_deferred():
            staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
        yield staging
        _visible_mode(staging, 0o777)
        with signals_deferred():
            _replace(staging, target, overwrite)
    except BaseException:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        raise


_LAUNCHERS = {
    ("_launch", "popen_spawn_posix.py"),
    ("_launch", "popen_forkserver.py"),
    ("_launch", "popen_fork.py"),
    ("_start_executor_manager_thread", "process.py"),  # a pool's thread and first workers
}
_RETRY_SECONDS = 0.02


def _launching_a_process(frame) -> bool:
    """Whether ``frame`` is inside the start of a process pool or the hand-over of its data to a
    new worker."""
    while frame is not None:
        code = frame.f_code
        if (code.co_name, os.path.basename(code.co_filename)) in _LAUNCHERS:
            return True
        frame = frame.f_back
    return False


def _raise_interrupt(signum, frame) -> None:
    """KeyboardInterrupt, unless a worker is being launched: then again in a few milliseconds.

    Interrupting the launch would leave the new worker reading a truncated hand-over and dying
    with a traceback; SIGALRM brings the interrupt back once the launch is over.
    """
    global _held
    if _depth:
        _held = signum
        return
    if _launching_a_process(frame):
        signal.signal(signal.SIGALRM, _raise_interrupt)
        signal.setitimer(signal.ITIMER_REAL, _RETRY_SECONDS)
        return
    raise KeyboardInterrupt(f"signal {signum}")


def stop_listening() -> None:
    """Ignore SIGINT, SIGTERM and a pending retry from now on: the interrupt has been handled.

    Called once the clean-up has run and the process is about to exit, so that a second signal
    (or a retry armed during a worker launch) cannot turn the exit code 130 into a death by
    SIGINT halfway through the final message.
    """
    with contextlib.suppress(ValueError):  # not the main thread
        signal.setitimer(signal.ITIMER_REAL, 0)
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
            signal.signal(signum, signal.SIG_IGN)


def sigterm_as_interrupt() -> None:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt in the main thread, so clean-up code runs.

    Importing pycolmap installs its own SIGTERM handler (a stack dump, then death, with no
    clean-up): call this again once pycolmap is imported, before writing anything.
    """
    with contextlib.suppress(ValueError):  # not the main thread: leave the defaults
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _raise_interrupt)
        signal.signal(signal.SIGTERM, _raise_interrupt)
