"""Running a fleet's tasks: on a local process pool, or on a Dask cluster, each valve's result
handed back as soon as it is done.

Both executors run the same task function, :func:`run_valve`, which never raises for a valve's
own trouble: a log the loaders refuse, a model that cannot be fitted to it, even a bug, becomes
that valve's failure record, and the fleet goes on. Only an interruption (Ctrl-C, SIGTERM) stops
the batch; the executor then cancels what is queued and stops its workers, and what was already
written stays (:mod:`.results`), so a rerun resumes.

One valve, one thread: the processes are the parallelism. A fit differentiates its parameters on
threads of its own (:mod:`surrogate.core.parallel`) and NumPy's BLAS starts threads too; two workers
each starting two threads on two cores contend with each other and run slower than without
(:func:`surrogate.maps.crossval._one_thread` measured four times slower for the maps' training).
Each task keeps to one thread (:func:`one_thread`) and a local pool's workers start as fresh
interpreters (spawn: a forked copy of a process that ran PyTorch's thread pool can hang).

Dask is optional (the ``fleet`` extra) and imported only when ``--scheduler`` asks for it.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sys
import time
import traceback
from collections.abc import Iterator

from ..core import parallel
from ..data.errors import DataFileError
from ..core.errors import InputError
from .results import failure_record, task_identity
from .tasks import ValveTask
from .valve import valve_result

#: [s] to wait for a Dask scheduler to answer before calling its address wrong
CONNECT_TIMEOUT = 30
#: [s] the probe of the address before Dask connects: a refused port, a host that does not
#: answer, or a server that does not speak Dask's protocol is told within this
PROBE_TIMEOUT = 3.0
#: the schemes of a Dask scheduler's address (none: tcp)
SCHEMES = ("tcp", "tls")
#: the largest first message a scheduler sends [bytes]: its handshake is a small dict; a length
#: beyond this is another protocol's bytes read as one (an HTTP reply read as 3 EiB)
HANDSHAKE_MAX = 1 << 20
#: what installs Dask, for the message when it is missing
DASK_EXTRA = "pip install -c constraints.txt -e '.[fleet]'"
#: [s] a stopped local worker gets to exit before it is killed
STOP_GRACE = 5.0


def run_valve(task: ValveTask) -> dict:
    """The task function both executors run: the valve's result record (:mod:`.results`), or its
    failure with the error located (file, line, column for a refused log). Never raises but for
    an interruption."""
    began = time.perf_counter()
    record = task_identity(task)
    keep_freed_memory()
    try:
        with one_thread():
            record.update(valve_result(task))
        record["status"] = "ok"
    except InputError as error:
        problems = ([vars(problem) for problem in error.problems]
                    if isinstance(error, DataFileError) else None)
        record.update(failure_record(task, "bad input", str(error), problems=problems))
    except Exception as error:  # noqa: BLE001  (a bug: this valve fails, the fleet goes on)
        record.update(failure_record(task, "internal error", f"{type(error).__name__}: {error}",
                                     details=traceback.format_exc()))
    record["seconds"] = round(time.perf_counter() - began, 2)
    record["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return record


#: [bytes] free memory glibc keeps at the top of the heap instead of returning it at once
TRIM_THRESHOLD = 1 << 27
#: glibc's mallopt parameter number for the trim threshold (malloc.h: M_TRIM_THRESHOLD)
_M_TRIM_THRESHOLD = -1


def keep_freed_memory() -> None:
    """Raise this process's glibc trim threshold to :data:`TRIM_THRESHOLD` (elsewhere: nothing).

    Dask's nanny starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which hands freed
    memory back to the system almost at once; a replay allocates and frees arrays of the log's
    size thousands of times, and each fit then ran 1.6 times slower than in a plain process
    (eval/virtual_fleet.py: a 2-worker LocalCluster fitted 1.3 times as many valves a minute as one
    worker, against 1.9 times with the threshold raised). The memory kept is a few arrays of one
    log, bounded by the threshold."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    except (OSError, AttributeError):  # not glibc (musl, say): its allocator is its own
        pass


@contextlib.contextmanager
def one_thread():
    """Keep this process to one thread of math while the block runs: the package's own thread
    pools (:data:`surrogate.core.parallel.THREAD_LIMIT`), the BLAS, and PyTorch's."""
    from threadpoolctl import threadpool_limits

    os.environ.setdefault("OMP_NUM_THREADS", "1")  # read by PyTorch if the task imports it
    kept = parallel.THREAD_LIMIT
    parallel.THREAD_LIMIT = 1
    torch = sys.modules.get("torch")
    torch_threads = torch.get_num_threads() if torch is not None else None
    if torch is not None:
        torch.set_num_threads(1)
    try:
        with threadpool_limits(1):
            yield
    finally:
        parallel.THREAD_LIMIT = kept
        if torch is not None:
            torch.set_num_threads(torch_threads)


def _worker_start() -> None:
    """A local worker's start: Ctrl-C is the driver's to handle (it stops the workers), and one
    thread of math from the first import on."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ["OMP_NUM_THREADS"] = "1"
    parallel.THREAD_LIMIT = 1


class LocalPool:
    """``workers`` fresh processes on this machine, one valve each at a time."""

    def __init__(self, workers: int):
        self.workers = workers

    def describe(self) -> str:
        return f"{self.workers} local worker process{'es' if self.workers != 1 else ''}"

    def check(self) -> None:
        """Nothing to check before work: a local pool needs nothing set up."""

    def results(self, tasks: list[ValveTask]) -> Iterator[dict]:
        """Each task's record, in the order they complete."""
        if not tasks:
            return
        # imported here: every command's start would otherwise pay for the process machinery
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        pool = ProcessPoolExecutor(min(self.workers, len(tasks)),
                                   mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_worker_start)
        try:
            futures = {pool.submit(run_valve, task): task for task in tasks}
            for future in as_completed(futures):
                try:
                    record = future.result()
                except Exception as error:  # noqa: BLE001  (its worker died: killed, out of memory)
                    record = {**task_identity(futures[future]), **failure_record(
                        futures[future], "internal error",
                        f"the worker process stopped: {type(error).__name__}: {error}")}
                yield record
        except BaseException:  # Ctrl-C, SIGTERM, or the caller gave up: stop every worker now
            _stop(pool)
            raise
        pool.shutdown(wait=True)


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued and end the workers at once, not after their current valve (the
    pool's own shutdown would wait for it)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    deadline = time.monotonic() + STOP_GRACE
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.kill()


def scheduler_endpoint(address: str, source: str = "--scheduler") -> tuple[str, str, int]:
    """(scheme, host, port) of a Dask scheduler's address (``tcp://host:8786``, or
    ``host:8786``), or InputError saying what a scheduler's address looks like."""
    scheme, _, rest = address.rpartition("://")
    scheme = scheme or "tcp"
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")  # an IPv6 address in brackets
    hint = ("give the address `dask scheduler` prints, such as tcp://host:8786 (8786 is the "
            "scheduler's port; the dashboard's, 8787, speaks HTTP)")
    if scheme not in SCHEMES or not host or not port.isdigit() or not 0 < int(port) < 65536 \
            or any(not character.isprintable() or character.isspace() for character in host):
        raise InputError(f"{source} {address!r}: not a scheduler's address; {hint}")
    return scheme, host, int(port)


def probe_scheduler(address: str, source: str = "--scheduler",
                    timeout: float = PROBE_TIMEOUT) -> None:
    """Refuse, within seconds, an address where no Dask scheduler listens: a malformed one,
    a refused port, a host that does not answer, or a server that speaks another protocol
    (Dask's reads a length from the first bytes and would try to allocate exabytes for an HTTP
    reply). A scheduler greets a new connection with its handshake, a frame whose first 8 bytes
    are its (small) length; the probe reads them and closes."""
    scheme, host, port = scheduler_endpoint(address, source)
    where = f"{source} {address}"
    try:
        with socket.create_connection((host, port), timeout=timeout) as connection:
            if scheme != "tcp":  # TLS: the greeting is encrypted; reaching the port is the check
                return
            connection.settimeout(timeout)
            greeting = b""
            while len(greeting) < 8:
                chunk = connection.recv(8 - len(greeting))
                if not chunk:
                    break
                greeting += chunk
    except socket.gaierror as error:
        raise InputError(f"{where}: no such host ({error.strerror or error})") from None
    except TimeoutError:
        raise InputError(f"{where}: nothing answered within {timeout:g} s as a Dask scheduler "
                         "does (it greets a new connection at once); check the host and the "
                         "port (8786 by default)") from None
    except OSError as error:
        raise InputError(f"{where}: cannot connect ({error.strerror or error}); is a Dask "
                         "scheduler running there? Start one with `dask scheduler`") from None
    length = int.from_bytes(greeting.ljust(8, b"\0"), "little")
    if len(greeting) < 8 or not 0 < length <= HANDSHAKE_MAX:
        what = ("an HTTP server (a Dask dashboard's port?)" if greeting.startswith(b"HTTP")
                else "a server that closed the connection" if not greeting
                else "a server that does not speak Dask's protocol")
        raise InputError(f"{where}: {what} answers there, not a Dask scheduler; give the "
                         "scheduler's port (8786 by default, as `dask scheduler` prints it)")


class DaskCluster:
    """The Dask distributed scheduler at ``address``; its workers must have this package
    installed and see the logs at the same paths (a shared file system)."""

    def __init__(self, address: str, source: str = "--scheduler"):
        self.address, self.source = address, source
        self.client = None
        self.probed = False

    def describe(self) -> str:
        return f"the Dask scheduler at {self.address}"

    def reachable(self) -> None:
        """Within seconds, before any work: Dask is installed and a scheduler answers at the
        address (:func:`probe_scheduler`); else InputError, the command line's mistake. Probed
        once: each probe is a connection the scheduler logs as a failed handshake."""
        if self.probed:
            return
        try:
            import distributed  # noqa: F401  (the fleet extra's)
        except ImportError:
            raise InputError(f"{self.source} {self.address}: running on a Dask cluster needs "
                             f"Dask, which is not installed; install the fleet extra "
                             f"({DASK_EXTRA}), or leave out {self.source} to run on this "
                             "machine") from None
        probe_scheduler(self.address, self.source)
        self.probed = True

    def check(self) -> None:
        """Connect, before any work: a missing Dask or a scheduler that does not answer is the
        command line's mistake (exit 2)."""
        self.reachable()
        from distributed import Client

        try:
            self.client = Client(self.address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as error:
            raise InputError(f"{self.source} {self.address}: no Dask scheduler answered there "
                             f"within {CONNECT_TIMEOUT} s ({type(error).__name__}: {error}); "
                             "give the address `dask scheduler` prints, such as "
                             "tcp://host:8786") from None

    def results(self, tasks: list[ValveTask]) -> Iterator[dict]:
        """Each task's record, in the order they complete."""
        from distributed import as_completed as completed

        if self.client is None:
            self.check()
        futures = {}
        try:
            for task in tasks:
                # a key of its own per submission: a rerun of a valve must not reuse a result
                # the scheduler still holds from before its log changed
                future = self.client.submit(run_valve, task, pure=False,
                                            key=f"fleet-{task.serial}-{os.urandom(6).hex()}")
                futures[future] = task
            # this client is not the default one: the iterator must be told its event loop
            for future in completed(list(futures), loop=self.client.loop):
                try:
                    record = future.result()
                except Exception as error:  # noqa: BLE001  (a worker died on it: KilledWorker)
                    record = {**task_identity(futures[future]), **failure_record(
                        futures[future], "internal error",
                        f"the Dask task failed: {type(error).__name__}: {error}")}
                yield record
        except BaseException:
            if futures:
                self.client.cancel(list(futures))
            raise
        finally:
            self.close()

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
