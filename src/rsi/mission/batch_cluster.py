"""The batch's dask cluster: local worker processes started for one batch, or an existing cluster whose
scheduler address is probed before the client trusts it (docs/batch.md, docs/reliability.md).

Importing this module stays cheap: dask and distributed load when a cluster is opened.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
from collections.abc import Iterator
from typing import TYPE_CHECKING

from rsi.errors import InputError

if TYPE_CHECKING:
    from distributed import Client

CONNECT_TIMEOUT_S = 10.0
"""Default wait for an existing scheduler (and the workers asked for)."""
MAX_CONNECT_TIMEOUT_S = 3600.0
MAX_CLUSTER_WORKERS = 100_000
"""Most workers a batch waits for on an existing cluster."""
_MAX_HANDSHAKE_BYTES = 64 * 2**20


def max_local_workers() -> int:
    """Most local worker processes: two per usable core. One single-threaded process per core is the most
    that runs at once; past two per core they only add memory (each holds its own interpreter and images)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return 2 * max(cores, 1)


@contextlib.contextmanager
def environment_kept() -> Iterator[None]:
    """This process's environment put back as it was when the block ends.

    A dask nanny writes its workers' settings (``OMP_NUM_THREADS=1``, ``MALLOC_TRIM_THRESHOLD_``,
    ``PYTHONHASHSEED``, ...) into the *parent's* ``os.environ`` before it spawns them, and leaves them there.
    Every process the caller starts later inherits them: with the trim threshold set, glibc turns off its
    dynamic mmap threshold and each image-sized numpy temporary faults in fresh zeroed pages (the console's
    camera process, spawned after a batch in the same interpreter, took 86 ms a frame instead of 36).
    """
    saved = dict(os.environ)
    try:
        yield
    finally:
        for name in set(os.environ) - set(saved):
            del os.environ[name]
        for name, value in saved.items():
            if os.environ.get(name) != value:
                os.environ[name] = value


@contextlib.contextmanager
def open_cluster(scheduler: str | None, workers: int | None, timeout_s: float) -> Iterator[Client]:
    """A client of local worker processes (`scheduler` None: `workers` of them, default the CPU count), or
    of the cluster at `scheduler` once it has at least `workers` workers; closed (local: shut down) on exit.

    The arguments are checked by :func:`rsi.mission.batch.run_batch`.
    """
    if scheduler is None:
        with _local_client(workers) as client:
            yield client
    else:
        with _remote_client(scheduler, workers, timeout_s) as client:
            yield client


@contextlib.contextmanager
def _local_client(workers: int | None) -> Iterator[Client]:
    import dask
    from distributed import Client, LocalCluster

    # Processes, one thread each: the detector holds the GIL between OpenCV calls, so threads would not
    # scale. Every port is chosen by the OS (":0": the scheduler's HTTP server otherwise tries 8787 and
    # warns when it is taken) and bound to the loopback interface only: the cluster is private.
    with (
        environment_kept(),
        # distributed sets MALLOC_TRIM_THRESHOLD_ in its workers; an explicit trim threshold turns off
        # glibc's dynamic mmap threshold, so every image-sized temporary becomes a fresh mmap whose pages
        # fault in zeroed: 43 -> 80 ms per 640x640 pair here. A task keeps nothing between pairs, so
        # trimming buys nothing.
        dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}),
        LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=":0",
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,  # type: ignore[no-untyped-call]
    ):
        yield client


@contextlib.contextmanager
def _remote_client(scheduler: str, workers: int | None, timeout_s: float) -> Iterator[Client]:
    from distributed import Client

    _probe_handshake(scheduler, timeout_s)
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s")  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as error:
        reason = " ".join(str(error).split()) or type(error).__name__
        raise InputError(
            f"scheduler={scheduler!r} cannot be reached ({reason[:300]}). "
            "Give the address a running `dask scheduler` prints (tcp://host:8786), or omit it for local "
            "worker processes."
        ) from None
    except (Exception, MemoryError) as error:
        # Something answered that is not a dask scheduler: its bytes, read as dask frames, give absurd
        # lengths (a MemoryError from allocating one) or garbage. The handshake failed; nothing was allocated.
        raise InputError(
            f"scheduler={scheduler!r} answered, but not as a dask scheduler (handshake failed: "
            f"{type(error).__name__}). Check the address and port (`dask scheduler` prints them)."
        ) from None
    with client:
        if workers is not None:
            try:
                client.wait_for_workers(workers, timeout=timeout_s)
            except TimeoutError:
                have = len(client.scheduler_info()["workers"])
                raise InputError(
                    f"workers={workers}: the cluster at {scheduler!r} has {have} worker(s) after "
                    f"{timeout_s:g} s. Start more workers or ask for fewer."
                ) from None
        yield client


def _probe_handshake(scheduler: str, timeout_s: float) -> None:
    """Check that a TCP scheduler address answers like dask before the client trusts it.

    A dask scheduler writes its handshake as soon as a connection is accepted: an 8-byte little-endian
    length, then a few dozen bytes. A server that says nothing would make the client wait forever, and one
    that says something else gives the client an absurd length to allocate (a MemoryError). A scheduler
    refusing the connection is not there; other failures (an unknown host) and other schemes (tls://) are
    left to the client, which names the reason.
    """
    scheme, _, rest = scheduler.strip().rpartition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("", "tcp") or not port.isdigit() or not host:
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s) as connection:
            connection.settimeout(timeout_s)
            prelude = connection.recv(8, socket.MSG_WAITALL)
    except ConnectionRefusedError:
        raise InputError(
            f"scheduler={scheduler!r} cannot be reached (connection refused: nothing listens there). Give "
            "the address a running `dask scheduler` prints (tcp://host:8786), or omit it for local workers."
        ) from None
    except TimeoutError:
        raise InputError(
            f"scheduler={scheduler!r} accepted the connection but sent no dask handshake within "
            f"{timeout_s:g} s (connect_timeout_s). Check the address and port (`dask scheduler` prints them)."
        ) from None
    except OSError:
        return
    length = int.from_bytes(prelude, "little") if len(prelude) == 8 else 0
    if not 0 < length <= _MAX_HANDSHAKE_BYTES:
        raise InputError(
            f"scheduler={scheduler!r} answered, but not as a dask scheduler (its first bytes {prelude!r}). "
            "Check the address and port (`dask scheduler` prints them)."
        )
