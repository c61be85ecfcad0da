"""The cluster of the distributed tests: a LocalCluster of two worker processes, one per module."""

from __future__ import annotations

import os
import signal

import pytest


@pytest.fixture(scope="module")
def client():
    distributed = pytest.importorskip("dask.distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture
def killer(client):
    """A progress callback that SIGKILLs a busy worker once 3 bricks have finished, and the
    list of the addresses it killed (Dask's nanny starts a new worker)."""
    killed: list[str] = []

    def kill_one(done, total):
        if done == 3 and not killed:  # a few bricks finished, many to go: kill a worker that is busy
            busy = [addr for addr, keys in client.processing().items() if keys]
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            killed.append(busy[0])
            os.kill(pid, signal.SIGKILL)

    return kill_one, killed
