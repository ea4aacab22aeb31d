"""Where batch runs execute: a local process pool over every core, or a Dask distributed cluster.

Both are `concurrent.futures` executors. Drake Diagrams neither pickle nor survive a fork, so jobs
carry plain scenarios and each worker process builds (and keeps) its own Diagrams; the local pool
uses the `spawn` start method.
"""

import contextlib
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor


@contextlib.contextmanager
def make_executor(*, workers=None, scheduler=None):
    """Yield an executor: Dask's at `scheduler` (an address such as tcp://host:8786) if given,
    else a local pool of `workers` processes (default: every core)."""
    if scheduler:
        from distributed import Client

        client = Client(scheduler)
        try:
            yield client.get_executor()
        finally:
            client.close()
    else:
        with ProcessPoolExecutor(
            max_workers=workers or os.cpu_count() or 1, mp_context=multiprocessing.get_context("spawn")
        ) as pool:
            yield pool
