"""All-or-nothing output: files and folders built beside their target and renamed into place.

A target that already exists is never touched unless ``overwrite`` is given; then it is replaced
only after the new content is complete. An exception, a KeyboardInterrupt or (after
:func:`sigterm_as_interrupt`) a SIGTERM removes the temporary sibling and leaves the target as
it was.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, NoReturn

__all__ = [
    "CLI_REPLACE_HINT",
    "API_REPLACE_HINT",
    "check_target",
    "check_apart",
    "settled",
    "names_a_stream",
    "linked_output",
    "staging_folder",
    "remove_stale",
    "atomic_file",
    "atomic_directory",
    "signals_deferred",
    "sigterm_as_interrupt",
    "stop_listening",
    "worker_pool",
    "WorkerPool",
    "worker_count",
    "available_cpus",
    "import_pycolmap",
    "interrupt_exit_code",
]


CLI_REPLACE_HINT = "pass --overwrite to replace it"
API_REPLACE_HINT = "pass overwrite=True to replace it"


def check_target(
    path: str | os.PathLike,
    kind: str,
    overwrite: bool = False,
    inputs: Iterable[str | os.PathLike] = (),
    name: str = "",
    replace_hint: str = CLI_REPLACE_HINT,
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
    replace_hint : str
        How the message for an existing output says to replace it: the command line's
        ``--overwrite`` (:data:`CLI_REPLACE_HINT`) or the API's (:data:`API_REPLACE_HINT`).

    Returns
    -------
    pathlib.Path
        ``path`` with the ``..`` and symbolic links of its folder resolved (:func:`settled`), its
        parent folder existing and writable; the file or folder a symbolic link named by
        ``path`` leads to (:func:`linked_output`), so that the link is kept.
    """
    if type(overwrite).__name__ not in ("bool", "bool_"):  # numpy not loaded for the CLI's start
        raise TypeError(f"overwrite must be True or False, got {type(overwrite).__name__}")
    _require_short_names(Path(path))
    target = linked_output(path, kind)
    for named in dict.fromkeys((Path(path), target)):  # /dev/stdout leads to a regular file
        if names_a_stream(named):
            raise ValueError(
                f"cannot write {named}: {settled(named).parent} holds devices and streams (such "
                "as /dev/stdout), which an output renamed into place would replace; give "
                "another path"
            )
    _require_short_names(target)
    parent = target.parent
    for ancestor in (parent, *parent.parents):
        if ancestor.exists() and not ancestor.is_dir():
            raise ValueError(f"cannot write {target}: {ancestor} is a file, not a folder")
        if ancestor.exists():
            break
    if target.is_symlink() and not target.exists() and not overwrite:
        raise ValueError(
            f"{target} is a symbolic link to {os.readlink(target)}, which leads nowhere; "
            f"{replace_hint}"
        )
    if kind == "file":
        if target.is_dir() or str(path).endswith(os.sep):
            raise ValueError(f"{target} is a folder; give a file name")
        check_apart(target, inputs, name)
        if not parent.is_dir():
            raise ValueError(f"cannot write {target}: folder {parent} does not exist")
        if target.exists() and not target.is_file():  # before the hint to replace it
            raise ValueError(
                f"{target} is not a regular file (a device, a pipe or a socket), which no "
                "output file replaces; give a file name"
            )
        if target.exists() and not overwrite:
            raise ValueError(f"{target} already exists; {replace_hint}")
    else:
        check_apart(target, inputs, name)
        if target.exists() and not target.is_dir():
            raise ValueError(f"{target} is a file, not a folder")
        if target.is_dir() and _holds_current_folder(target):
            raise ValueError(
                f"cannot write {target}: it is or holds the current folder, which a new output "
                "folder cannot replace; give another folder"
            )
        if target.is_dir() and any(target.iterdir()) and not overwrite:
            raise ValueError(f"{target} exists and is not an empty directory; {replace_hint}")
        if target.is_dir() and not os.access(target, os.W_OK | os.X_OK):
            # it is moved aside at the end, which needs the folder writable (root too, when
            # the folder is immutable or on a read-only file system)
            raise ValueError(f"cannot replace {target}: the folder is not writable")
    existing = next((p for p in (parent, *parent.parents) if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"cannot write {target}: {existing} is not writable")
    return settled(target)


def linked_output(path: str | os.PathLike, kind: str) -> Path:
    """Where an output ``path`` of ``kind`` (``"file"`` or ``"folder"``) is written: the file
    or folder it leads to when it is a symbolic link to one of that kind, which is kept
    (``out -> /data/out`` writes ``/data/out``), ``path`` itself otherwise. A link that leads
    nowhere is refused, or with ``overwrite`` replaced (:func:`check_target`)."""
    target = Path(path)
    try:
        linked = target.is_symlink() and (target.is_dir() if kind == "folder" else target.is_file())
    except OSError:  # a name too long, a loop: check_target names the problem
        return target
    return Path(os.path.realpath(target)) if linked else target


def names_a_stream(path: str | os.PathLike) -> bool:
    """Whether ``path`` lies in ``/dev`` or ``/proc`` (``/dev/stdout``, ``/dev/fd/1``,
    ``/dev/null``), where a file renamed into place would replace a device or a stream of the
    process, even when the stream is redirected to a regular file."""
    folder = settled(path).parent
    return folder == Path("/dev") or Path("/proc") in (folder, *folder.parents)


def settled(path: str | os.PathLike) -> Path:
    """``path`` with the ``..`` and symbolic links of its folder resolved, its own name kept.

    An output is built beside its target and renamed onto it; a target spelled through itself
    (``out/sub/../../out``) would lose its folder when set aside, and the new output with it.
    """
    target = Path(path)
    if target.name in ("", ".."):
        return Path(os.path.realpath(target))
    return Path(os.path.realpath(target.parent)) / target.name


def _holds_current_folder(folder: Path) -> bool:
    """Whether the working folder is ``folder`` or inside it (``.``, ``..``): a finished output
    moved onto it would find it busy, or leave the process in a deleted folder."""
    try:
        here = Path.cwd().resolve()
    except OSError:  # the working folder was deleted
        return False
    resolved = folder.resolve()
    return here == resolved or resolved in here.parents


STAGING_NAME_EXTRA = 20
"""Bytes a staging name (``.NAME.PID.XXXXXXXX``, ``.NAME.old.XXXXXXXX``) adds to the name of
its target."""


def _require_short_names(target: Path) -> None:
    """ValueError when ``target``'s staging name, or a folder to create on the way to it, is
    longer than its file system allows: the error would come after the work, naming a hidden
    file."""
    limit, missing = 255, []
    for folder in (target.parent, *target.parent.parents):
        try:
            limit = os.pathconf(folder, "PC_NAME_MAX")
            break
        except (OSError, ValueError):
            missing.append(folder)
    for folder in missing:
        if len(os.fsencode(folder.name)) > limit:
            raise ValueError(
                f"cannot write {target}: folder name {folder.name[:40]!r}... is "
                f"{len(os.fsencode(folder.name))} bytes, above the {limit} the file system allows"
            )
    allowed = limit - STAGING_NAME_EXTRA
    if len(os.fsencode(target.name)) > allowed:
        raise ValueError(
            f"cannot write {target}: its name is {len(os.fsencode(target.name))} bytes; the "
            f"file system allows {limit}, of which {STAGING_NAME_EXTRA} go to the hidden name it "
            f"is built under, so at most {allowed}"
        )


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
_received: list[int] = []  # the signals :func:`_raise_interrupt` was called for
_depth = 0


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back until the block is over.

    Creating a temporary entry and entering the ``try`` that removes it, or swapping an output
    into place, must not be split by an interrupt; a signal that arrives meanwhile is delivered,
    and its KeyboardInterrupt raised, as soon as the block ends. The signals are blocked in
    this thread, and one that the kernel hands to another thread (numpy's and OpenCV's workers
    do not block it) is held by :func:`_raise_interrupt` until the block ends.
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
            handler = signal.getsignal(held)
            if handler is _raise_interrupt:
                handler(held, None)
            raise KeyboardInterrupt(f"signal {held}")


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask, as ``taskset`` or a container's
    limit sets it), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def worker_count(requested: int | None, jobs: int) -> int:
    """Worker processes for ``jobs`` jobs: ``requested`` (0 or None: one per available CPU),
    capped at the jobs and the available CPUs (more would only add start-up time and memory),
    at least 1."""
    return max(1, min(requested or available_cpus(), available_cpus(), jobs))


@contextlib.contextmanager
def worker_pool(workers: int, initializer: Callable[[], None]) -> Iterator[WorkerPool]:
    """A :class:`WorkerPool` of ``workers`` spawned processes, stopped on any error.

    ``initializer`` (a module-level function: it is pickled) runs in each worker; it imports
    pycolmap, if at all, through :func:`import_pycolmap`. On an exception or an interrupt in
    the block the workers are killed and joined before it propagates: none is left writing
    into an output the caller then removes.
    """
    _block_signals_in_new_workers()
    pool = None
    try:
        with signals_deferred():
            pool = WorkerPool(workers, initializer)
        yield pool
    except BaseException:
        if pool is not None:
            pool.kill()
        raise
    pool.close()


class WorkerPool:
    """Spawned worker processes, each fed through a pipe of its own.

    No lock or queue is shared between the workers, so that one killed anywhere (the SIGTERM
    that ``timeout`` or a service manager sends reaches the whole process group) cannot leave
    the others or this process waiting: its pipe ends, and the pool reports it.

    A worker starts with SIGINT and SIGTERM blocked until it has set its handlers: it ignores
    SIGINT (Ctrl-C is the parent's to handle) and dies at SIGTERM, quietly.
    """

    def __init__(self, workers: int, initializer: Callable[[], None]) -> None:
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        self.processes, self._pipes = [], []
        self._signals_before = len(_received)
        for _ in range(workers):
            mine, theirs = context.Pipe()
            process = context.Process(target=_serve, args=(theirs, initializer), daemon=True)
            self.processes.append(process)
            self._pipes.append(mine)
            process.start()
            theirs.close()

    def imap(self, function: Callable[[Any], Any], jobs: Iterable[Any]) -> Iterator[Any]:
        """``function(job)`` for each job, computed in the workers, yielded in order."""
        from multiprocessing.connection import wait

        queue = enumerate(jobs)
        busy, done, following = {}, {}, 0

        def give(pipe) -> None:
            for index, job in queue:
                pipe.send((function, job))
                busy[pipe] = index
                return

        for pipe in self._pipes:
            give(pipe)
        while busy or done:
            while following in done:
                yield done.pop(following)
                following += 1
            for pipe in wait(list(busy)) if busy else ():
                try:
                    failed, value = pipe.recv()
                except (EOFError, OSError):
                    self._died(pipe)
                if failed:
                    raise value
                done[busy.pop(pipe)] = value
                give(pipe)

    def _died(self, pipe) -> NoReturn:
        """ChildProcessError naming how the worker of ``pipe`` ended; KeyboardInterrupt when
        this process was interrupted too (a signal to the whole group)."""
        process = self.processes[self._pipes.index(pipe)]
        process.join(timeout=1.0)
        if len(_received) > self._signals_before:
            raise KeyboardInterrupt(f"signal {_received[-1]}")
        code = process.exitcode
        how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit {code}"
        raise ChildProcessError(f"a worker process died ({how})")

    def map(self, function: Callable[[Any], Any], jobs: Iterable[Any]) -> list[Any]:
        """``function(job)`` for each job, computed in the workers, in order."""
        return list(self.imap(function, jobs))

    def close(self) -> None:
        """Let the workers finish and wait for them."""
        for pipe in self._pipes:
            with contextlib.suppress(OSError):
                pipe.send(None)
        for process in self.processes:
            process.join()
        for pipe in self._pipes:
            pipe.close()

    def kill(self) -> None:
        """Kill the workers, whatever they are doing, and wait for them."""
        for process in self.processes:
            if process.pid is not None:
                process.kill()
                process.join()
        for pipe in self._pipes:
            pipe.close()


def _serve(pipe, initializer: Callable[[], None]) -> None:
    """A worker of :class:`WorkerPool`: its signal handlers, ``initializer``, then the jobs
    it is sent until ``None``; an exception goes back to the pool."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _DEFERRED)
    initializer()
    with contextlib.suppress(EOFError, BrokenPipeError):  # the pool's process has ended
        while (task := pipe.recv()) is not None:
            function, job = task
            try:
                outcome = (False, function(job))
            except Exception as error:
                outcome = (True, error)
            pipe.send(outcome)


def _block_signals_in_new_workers() -> None:
    """Launch spawned processes with SIGINT and SIGTERM blocked from their first instruction
    (the mask is inherited through fork and exec)."""
    from multiprocessing import popen_spawn_posix

    launch = popen_spawn_posix.Popen._launch
    if getattr(launch, "blocks_signals", False):
        return

    def launch_blocking_signals(self, process_obj):
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, _DEFERRED)
        try:
            return launch(self, process_obj)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)

    launch_blocking_signals.blocks_signals = True
    popen_spawn_posix.Popen._launch = launch_blocking_signals


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_stale(target: Path) -> list[Path]:
    """Remove the temporary siblings of ``target`` that a killed run left (SIGKILL, a power
    cut): those named by :func:`staging_folder` or :func:`atomic_file` after a process that
    no longer runs. Returns what was removed."""
    pattern = re.compile(rf"\.{re.escape(target.name)}\.(\d+)\.[a-z0-9_]{{8}}")
    removed = []
    with contextlib.suppress(OSError):
        for entry in target.parent.iterdir():
            found = pattern.fullmatch(entry.name)
            if found is None or _process_alive(int(found[1])):
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)
            removed.append(entry)
    return removed


def staging_folder(target: str | os.PathLike) -> Path:
    """A new hidden folder beside ``target``, named after it and this process, in which to
    build it; the ones a killed run left there are removed first (:func:`remove_stale`)."""
    target = Path(target)
    remove_stale(target)
    return Path(tempfile.mkdtemp(prefix=f".{target.name}.{os.getpid()}.", dir=target.parent))


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
    try:
        os.rename(target, aside / "old")
        try:
            os.rename(staging, target)
        except BaseException:
            os.rename(aside / "old", target)
            raise
    finally:
        shutil.rmtree(aside, ignore_errors=True)


def _unnamed_file(folder: Path) -> int | None:
    """A descriptor of a new file in ``folder`` that has no name yet (Linux ``O_TMPFILE``): a
    process killed before it is linked leaves nothing. None where the file system has none."""
    try:
        return os.open(folder, os.O_TMPFILE | os.O_WRONLY, 0o666)
    except (AttributeError, OSError):
        return None


def _link_into_place(descriptor: int, target: Path, overwrite: bool) -> None:
    """Give the unnamed file of ``descriptor`` the name ``target`` (replaced with
    ``overwrite``: through a sibling name that exists only for the rename)."""
    folder = os.open(target.parent, os.O_RDONLY | os.O_DIRECTORY)
    try:  # a folder descriptor makes os.link call linkat, which follows the /proc link
        if not (target.exists() or target.is_symlink()):
            os.link(f"/proc/self/fd/{descriptor}", target.name, dst_dir_fd=folder)
            return
        while True:
            sibling = target.with_name(f".{target.name}.{os.urandom(4).hex()}")
            try:
                os.link(f"/proc/self/fd/{descriptor}", sibling.name, dst_dir_fd=folder)
                break
            except FileExistsError:
                continue
    finally:
        os.close(folder)
    try:
        _replace(sibling, target, overwrite)
    finally:
        sibling.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_file(
    path: str | os.PathLike, overwrite: bool = False, mode: str = "w"
) -> Iterator[object]:
    """Open a new file for writing; it becomes ``path`` only when the block succeeds.

    Yields the open file (text mode ``"w"`` in UTF-8, or ``"wb"``). The file has no name until
    then where the file system allows it (Linux ``O_TMPFILE``), so that even a process killed
    by SIGKILL leaves nothing behind; elsewhere it is a hidden temporary sibling of ``path``.
    On any exception, including KeyboardInterrupt, it is removed and ``path`` is left
    untouched.
    """
    target = check_target(path, "file", overwrite)
    staging = None
    try:
        with signals_deferred():
            descriptor = _unnamed_file(target.parent)
            if descriptor is None:
                remove_stale(target)
                descriptor, name = tempfile.mkstemp(
                    prefix=f".{target.name}.{os.getpid()}.", dir=target.parent
                )
                staging = Path(name)
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(descriptor, mode, encoding=encoding) as handle:
            yield handle
            handle.flush()
            if staging is None:
                with signals_deferred():
                    _link_into_place(descriptor, target, overwrite)
        if staging is not None:
            _visible_mode(staging, 0o666)
            with signals_deferred():
                _replace(staging, target, overwrite)
    except BaseException:
        if staging is not None:
            staging.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_directory(
    path: str | os.PathLike, overwrite: bool = False, replace_hint: str = CLI_REPLACE_HINT
) -> Iterator[Path]:
    """A temporary sibling folder of ``path``, renamed to ``path`` when the block succeeds.

    An empty existing folder is replaced; a non-empty one or a file only with ``overwrite``
    (:func:`check_target` with ``replace_hint``).
    On any exception the temporary folder is removed and ``path`` is left untouched; one that
    a killed run left is removed by the next run for the same ``path`` (:func:`staging_folder`).
    """
    target = check_target(path, "folder", overwrite, replace_hint=replace_hint)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = None
    try:
        with signals_deferred():
            staging = staging_folder(target)
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
    _received.append(signum)
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

    Called once the clean-up has run, or the work is done, and the process is about to exit,
    so that a second signal (or a retry armed during a worker launch) cannot turn the exit
    code into a death by signal halfway through the final message or the interpreter's exit.
    """
    with contextlib.suppress(ValueError):  # not the main thread
        signal.setitimer(signal.ITIMER_REAL, 0)
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
            signal.signal(signum, signal.SIG_IGN)


def sigterm_as_interrupt() -> None:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt in the main thread, so clean-up code runs.

    Importing pycolmap installs its own SIGTERM handler (a stack dump, then death, with no
    clean-up): import it through :func:`import_pycolmap`, which puts this one back.
    """
    with contextlib.suppress(ValueError):  # not the main thread: leave the defaults
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _raise_interrupt)
        signal.signal(signal.SIGTERM, _raise_interrupt)


def import_pycolmap():
    """Import pycolmap with SIGINT and SIGTERM held back, then handle SIGTERM as before.

    Importing pycolmap installs a native SIGTERM handler (a stack dump, then death, with no
    clean-up); the Python handler is put back, and a signal that arrived meanwhile delivered
    to it. Call it from the main thread, best before numpy is imported: the threads numpy
    starts then block the signals too, and none of them can take one while pycolmap's handler
    is in place.
    """
    import importlib

    with signals_deferred():
        handler = signal.getsignal(signal.SIGTERM)
        module = importlib.import_module("pycolmap")
        if handler is not None:
            signal.signal(signal.SIGTERM, handler)
    return module


def interrupt_exit_code() -> int:
    """The exit code of a run stopped by an interrupt: 143 after SIGTERM, else 130 (SIGINT)."""
    return 128 + signal.SIGTERM if _received and _received[-1] == signal.SIGTERM else 130
