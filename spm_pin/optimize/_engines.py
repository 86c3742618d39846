"""Where a study's designs are evaluated: this process, or a Dask distributed cluster.

The driver (the process that runs :func:`~spm_pin.optimize.run_study`) alone talks
to the study's storage: it asks Optuna for a trial, sends the evaluation of its
design values to the cluster, and tells Optuna the outcome when it comes back. The
evaluation is a plain top-level function of picklable arguments, so a worker needs
spm-pin installed and nothing else: no storage, no Optuna.

:func:`dask_client` gives the client: connected to an existing scheduler
(``tcp://host:port``), or to a :class:`distributed.LocalCluster` of worker processes
started for the study and closed after it. :func:`evaluate_on_cluster` keeps up to
:data:`IN_FLIGHT_PER_THREAD` evaluations in flight per worker thread and hands each
outcome back as it completes (``distributed.as_completed``): an evaluation that
raises, or whose worker died (``KilledWorker``), is handed back as the exception's
text, not raised.

Dask distributed is imported when a cluster is used (``pip install
'dask[distributed]'``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from ..errors import InputError, SPMError

__all__ = [
    "CONNECT_TIMEOUT_S",
    "IN_FLIGHT_PER_THREAD",
    "ClusterError",
    "dask_client",
    "evaluate_on_cluster",
    "local_cluster_options",
]

#: Evaluations kept in flight per worker thread of the cluster (one running, one
#: queued on it, so a worker never waits for the driver).
IN_FLIGHT_PER_THREAD = 2
#: Time allowed to connect to a scheduler [s].
CONNECT_TIMEOUT_S = 10.0

K = TypeVar("K")


class ClusterError(SPMError, RuntimeError):
    """The Dask cluster itself failed (the scheduler went away, the evaluations were
    cancelled): the study stops, its in-flight trials marked failed."""


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError as exc:
        raise ImportError(
            f"studies on several workers need Dask: pip install 'dask[distributed]' ({exc})"
        ) from None
    return distributed


@contextmanager
def dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A :class:`distributed.Client`: connected to ``scheduler``, or to a new
    ``LocalCluster`` of ``workers`` processes of one thread each (closed on exit).

    Raises:
        InputError: no scheduler answers at ``scheduler``.
        ImportError: Dask distributed is not installed.
    """
    distributed = _import_distributed()
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, ValueError, TypeError) as exc:
            raise InputError(
                f"scheduler {scheduler!r}: no Dask scheduler answers there ({exc}); "
                "start one with `dask scheduler` and give its address (tcp://host:8786)",
                argument="scheduler",
                value=scheduler,
            ) from None
        with client:
            yield client
        return
    with (
        distributed.LocalCluster(**local_cluster_options(workers)) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


def local_cluster_options(workers: int) -> dict[str, Any]:
    """The options of the ``LocalCluster`` of a study: ``workers`` processes of one
    thread, on this machine only, no dashboard (the scheduler's health server on a free
    port, not 8787, which another cluster may hold)."""
    return {
        "n_workers": workers,
        "threads_per_worker": 1,
        "processes": True,
        "host": "127.0.0.1",
        "dashboard_address": None,
        "scheduler_kwargs": {"dashboard_address": ":0"},
    }


def _capacity(client: Any) -> int:
    """Evaluations to keep in flight: per thread of the workers connected now (at
    least one thread, so a cluster still waiting for its workers gets some)."""
    threads = sum(client.nthreads().values())
    return IN_FLIGHT_PER_THREAD * max(1, int(threads))


def evaluate_on_cluster(
    client: Any,
    count: int,
    ask: Callable[[], tuple[K, tuple[Any, ...]]],
    task: Callable[..., Any],
    tell: Callable[[K, Any, str | None], None],
) -> None:
    """Evaluate ``count`` asked designs on the cluster of ``client``.

    Args:
        client: A :class:`distributed.Client`.
        count: How many to evaluate.
        ask: Returns (key, arguments of ``task``) of the next design (in the driver).
        task: The evaluation (a picklable top-level function: it runs on a worker).
        tell: Called in the driver with (key, result, None) when an evaluation
            completes, (key, None, reason) when it raised or its worker died.

    Raises:
        ClusterError: an evaluation was cancelled (the scheduler went away).

    Whatever this raises (Ctrl-C in the driver included), the evaluations still in
    flight are cancelled; their keys were not told.
    """
    distributed = _import_distributed()
    pending: dict[Any, K] = {}
    completed = distributed.as_completed()
    asked = 0

    def top_up() -> None:
        nonlocal asked
        capacity = _capacity(client)
        while asked < count and len(pending) < capacity:
            key, arguments = ask()
            asked += 1
            future = client.submit(task, *arguments, pure=False)
            pending[future] = key
            completed.add(future)

    try:
        top_up()
        for future in completed:
            key = pending.pop(future)
            if future.status == "cancelled":
                raise ClusterError(
                    f"the evaluation of {key} was cancelled by the Dask cluster "
                    "(did the scheduler stop?)"
                )
            if future.status == "error":
                exc = future.exception()
                tell(key, None, f"{type(exc).__name__}: {exc}")
            else:
                tell(key, future.result(), None)
            top_up()
    finally:
        if pending:
            client.cancel(list(pending))
