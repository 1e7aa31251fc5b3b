"""Running the cases of a sweep: in-process, on a local process pool, or on Dask.

Workers compute and return force series; the driver alone writes the store (see
:mod:`terradyn.sweep.store`), skipping finished cases, so a rerun resumes where a crash or
kill left off. One bad case records its error and the others go on.
"""
from __future__ import annotations

import os
import platform
import socket
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..errors import InputError
from .spec import SweepSpec, build, load

#: Environment variable naming the Dask scheduler (``tcp://host:8786``) when --scheduler is not given.
SCHEDULER_ENV = "TERRADYN_DASK_SCHEDULER"
#: How long to wait for the Dask scheduler to answer.
CONNECT_TIMEOUT = "20s"
THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass
class Summary:
    """What a run did: case counts, failures (id -> error line) and wall time (s)."""

    store: str
    total: int
    skipped: int = 0
    done: int = 0
    failed: dict = field(default_factory=dict)
    wall_s: float = 0.0
    executor: str = ""
    workers: int = 0

    @property
    def ok(self) -> bool:
        return not self.failed

    def to_dict(self) -> dict:
        return {"store": self.store, "total": self.total, "skipped": self.skipped, "done": self.done,
                "failed": self.failed, "wall_s": self.wall_s, "executor": self.executor,
                "workers": self.workers}


# ------------------------------------------------------------------------------------------
# the task (runs on a worker)
# ------------------------------------------------------------------------------------------
def _single_thread() -> None:
    """One compute thread per worker: set the thread variables (read when numba/BLAS load)
    and, if numba is already loaded, cap its pool now."""
    for v in THREAD_VARS:
        os.environ[v] = "1"
    import sys

    if "numba" in sys.modules:
        import numba

        numba.set_num_threads(1)


def simulate_case(params: dict, checkpoint: str | None = None):
    """Run one resolved case (see :func:`terradyn.sweep.spec.resolve`) -> force series,
    through the model registry (:mod:`terradyn.models`). ``checkpoint``: a file where a
    model that supports it (SPH) keeps its state (resumed by a rerun)."""
    from .. import models

    leg, motion = build(params)
    opts = dict(params["model"])
    model = models.get(opts.pop("name"), "sweep.model")
    medium = opts.pop("medium")
    opts = {**model.legacy, **opts}
    if checkpoint is not None and "checkpoint" in model.controls:
        opts["checkpoint"] = checkpoint
    return model.simulate(leg, motion, medium, **opts)


def run_case(cid: str, params: dict, single_thread: bool = True, checkpoint_dir: str | None = None):
    """The unit of work: simulate one case and return (cid, force series with provenance).
    ``checkpoint_dir``: where SPH cases checkpoint (``<dir>/<cid>.npz``)."""
    if single_thread:
        _single_thread()
    from .. import __version__
    import json

    t0, started = time.perf_counter(), time.time()
    ck = None
    from .. import models

    if checkpoint_dir and "checkpoint" in models.get(params["model"]["name"], "sweep.model").controls:
        Path(checkpoint_dir).mkdir(parents=True, exist_ok=True)
        ck = str(Path(checkpoint_dir) / f"{cid}.npz")
    ds = simulate_case(params, checkpoint=ck)
    wall = time.perf_counter() - t0
    ds.attrs.update(sweep_case_id=cid, sweep_params=json.dumps(params, sort_keys=True),
                    sweep_wall_time_s=wall, sweep_host=socket.gethostname(), sweep_pid=os.getpid(),
                    sweep_started=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(started)),
                    sweep_python=platform.python_version(), terradyn_version=__version__)
    return cid, ds


# ------------------------------------------------------------------------------------------
# executors: each yields (cid, dataset or None, error or None) as cases finish
# ------------------------------------------------------------------------------------------
def _err(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _tb(e: BaseException) -> str:
    return "".join(traceback.format_exception(type(e), e, e.__traceback__))[-4000:]


def _serial(todo, ck):
    for c in todo:
        try:
            yield run_case(c.id, c.params, False, ck) + (None,)
        except Exception as e:  # one bad case does not stop the others
            yield c.id, None, e


def _pool_init(driver_pid: int | None = None):
    _single_thread()
    if driver_pid is not None:
        _die_with(driver_pid)


def _die_with(driver_pid: int) -> None:
    """End this pool worker when the driver process dies.

    A SIGKILLed driver cannot shut its pool down, and its workers do not notice: each
    finishes its case (hours, for SPH) and then hangs for ever on the pool's pipes (seen:
    blocked writing its result, which nobody reads), while the rerun's own workers compete
    with them for the cores and, for an SPH case, for the same checkpoint file. On Linux the
    kernel kills the worker when the driver thread that started it (the one running the
    sweep) ends; elsewhere a thread polls the parent pid (it may wait for the GIL while a
    case runs)."""
    import signal
    import sys

    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0:  # 1 = PR_SET_PDEATHSIG
                if os.getppid() != driver_pid:  # died before prctl took effect
                    os._exit(1)
                return
        except (OSError, AttributeError):
            pass
    import threading

    def watch():
        while os.getppid() == driver_pid:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="terradyn-driver-watch", daemon=True).start()


def _local(todo, workers: int, ck):
    import multiprocessing as mp

    # spawn: workers start clean, read the thread variables before numba loads, and do not
    # inherit the driver's threads (fork after numba/BLAS threads start is unsafe).
    ctx = mp.get_context("spawn")
    ex = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_pool_init,
                             initargs=(os.getpid(),))
    finished = False
    try:
        futs = {ex.submit(run_case, c.id, c.params, True, ck): c.id for c in todo}
        for f in as_completed(futs):
            try:
                yield f.result() + (None,)
            except Exception as e:  # includes BrokenProcessPool: a worker died
                yield futs[f], None, e
        finished = True
    finally:
        # On Ctrl-C (or the consumer stopping) do not wait for queued cases.
        ex.shutdown(wait=finished, cancel_futures=True)


def _dask(todo, address: str, retries: int, ck, run_id: str):
    try:
        from distributed import Client, as_completed as d_completed
    except ImportError:  # pragma: no cover - a dependency
        raise InputError("scheduler", "Dask execution needs dask[distributed] installed") from None
    client, own = _existing_client(address), False
    if client is None:
        # A second Client in a process that has one (e.g. a notebook's) shares its event loop;
        # under load we saw that corrupt a connection, so an existing client is reused above.
        try:
            client, own = Client(address, timeout=CONNECT_TIMEOUT), True
        except (OSError, TimeoutError) as e:
            raise InputError("scheduler", f"cannot reach the Dask scheduler at {address!r} ({e})") from None
    try:
        futs = {}
        for c in todo:
            # The key names the case and this driver run (unique per run): the cluster's own
            # records (dashboard, worker logs) tell which run computed what, e.g. that a rerun
            # after a killed driver recomputed only the cases that run had not stored.
            f = client.submit(run_case, c.id, c.params, True, ck, key=task_key(c.id, run_id),
                              pure=False, retries=retries)
            futs[f.key] = (c.id, f)
        # with_results: the client fetches results concurrently as tasks finish, rather than
        # one blocking round trip per case from this loop.
        # raise_errors=False: a failed case yields (type, exception, traceback) instead of
        # run_case's (cid, dataset). Judge by that, not by f.status: once the result is
        # here, a worker killed later (that held it) turns the status to "lost" and a
        # finished case would be called failed.
        for f, res in d_completed([f for _, f in futs.values()], with_results=True, raise_errors=False):
            cid = futs.pop(f.key)[0]
            if isinstance(res, tuple) and len(res) == 2 and res[0] == cid:
                yield res + (None,)
            else:
                err = res[1] if isinstance(res, tuple) and len(res) == 3 else res
                yield cid, None, err if isinstance(err, BaseException) else RuntimeError(str(err))
            f.release()
    finally:
        if own:
            client.close()


def task_key(cid: str, run_id: str) -> str:
    """The Dask key of case ``cid`` submitted by the driver run ``run_id`` (the ``run`` of the
    store's events and the case file's ``sweep_run``)."""
    return f"terradyn-case-{cid}-{run_id}"


def _existing_client(address: str):
    """This process's default Dask client if it is connected to ``address``, else None."""
    try:
        from distributed import default_client

        c = default_client()
    except (ValueError, ImportError):
        return None
    try:
        same = c.status == "running" and c.scheduler.address == address
    except Exception:  # a closing client
        return None
    return c if same else None


# ------------------------------------------------------------------------------------------
# the driver
# ------------------------------------------------------------------------------------------
def default_store(spec: SweepSpec) -> Path:
    return Path(f"{spec.name}.sweep")


def check_stored_physics(st, spec: SweepSpec, done: set[str]) -> None:
    """Refuse to resume a store whose finished cases ran with other physical inputs than the
    ones this version's defaults give the same case (a model's ``physics``, e.g. SPH's
    shipped plate calibration): the store would mix two models under one case id."""
    import json
    import math

    from .. import models

    expected: dict[str, dict | None] = {}  # per distinct [model] table: cases share them
    for c in spec.cases:
        if c.id not in done:
            continue
        key = json.dumps(c.params["model"], sort_keys=True)
        if key not in expected:
            model = models.get(c.params["model"]["name"], "sweep.model")
            expected[key] = model.physics(c.params["model"]) if model.physics is not None else None
        now = expected[key]
        if now is None:
            continue
        stored = json.loads(st.read_case(c.id).attrs.get("input") or "{}").get("material")
        if not isinstance(stored, dict):
            continue  # recorded before materials were stored: nothing to compare
        for k, v in now.items():
            w = stored.get(k)
            same = (w == v) if not isinstance(v, float) or not isinstance(w, (int, float)) else \
                math.isclose(v, w, rel_tol=1e-9, abs_tol=1e-12)
            if not same:
                raise InputError("store", f"{st.path} holds case {c.id} made with material {k} = {w!r}; "
                                          f"this version gives {v!r} for the same case (e.g. a new shipped "
                                          "calibration): write to a new store, or set the value in the spec")


def run(spec: SweepSpec | str | Path, store: str | Path | None = None, *, workers: int | None = None,
        scheduler: str | None = None, retries: int = 0, checkpoint_dir: str | Path | None = None,
        progress: Callable[[int, int, str, bool], None] | None = None) -> Summary:
    """Run every unfinished case of ``spec`` into ``store`` (default ``<name>.sweep``).

    Executor: Dask when ``scheduler`` (or env ``TERRADYN_DASK_SCHEDULER``) names a scheduler
    address; else a local process pool of ``workers`` processes (default: all cores) with
    one compute thread each; ``workers=0`` runs in this process. ``retries``: extra attempts
    of a case that raised (Dask only; cases on a lost worker are rescheduled by Dask anyway).
    ``checkpoint_dir``: where long SPH cases keep resumable state (default: the store's
    ``checkpoints/`` for local runs; none on Dask unless given, as a path the workers see).
    ``progress(done, total, case_id, ok)`` is called after each case. Returns a
    :class:`Summary`; failed cases are recorded in the store and retried by the next run.
    """
    from .store import Store

    if not isinstance(spec, SweepSpec):
        spec = load(spec)
    scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or None
    if workers is not None and (not isinstance(workers, int) or workers < 0):
        raise InputError("workers", f"must be an integer >= 0, got {workers!r}")
    if not isinstance(retries, int) or retries < 0:
        raise InputError("retries", f"must be an integer >= 0, got {retries!r}")
    st = Store(store if store is not None else default_store(spec))
    st.claim(spec)
    st.lock()
    try:
        st.clean_temporaries()
        done = st.done_ids()
        check_stored_physics(st, spec, done)  # before anything is written
        st.write_plan(spec)
        todo = [c for c in spec.cases if c.id not in done]
        total = len(spec.cases)
        ck = str(checkpoint_dir or st.path / "checkpoints")
        run_id = os.urandom(6).hex()
        if scheduler:
            executor, nw = "dask", 0
            stream = _dask(todo, scheduler, retries, str(checkpoint_dir) if checkpoint_dir else None, run_id)
        elif workers == 0 or len(todo) <= 1:
            executor, nw = "serial", 1
            stream = _serial(todo, ck)
        else:
            nw = min(workers or os.cpu_count() or 1, len(todo))
            executor = "local"
            stream = _local(todo, nw, ck)
        summary = Summary(store=str(st.path), total=total, skipped=total - len(todo), executor=executor,
                          workers=nw)
        st.log("run-start", run=run_id, executor=executor, scheduler=scheduler, workers=nw,
               todo=len(todo), total=total, host=socket.gethostname(), pid=os.getpid())
        t0 = time.perf_counter()
        n = summary.skipped
        if progress:
            progress(n, total, "", True)
        for cid, ds, e in stream:
            n += 1
            if e is None:
                ds.attrs["sweep_run"] = run_id
                st.write_case(cid, ds)
                summary.done += 1
                st.log("case-done", run=run_id, case=cid, host=ds.attrs.get("sweep_host"),
                       pid=ds.attrs.get("sweep_pid"), wall_s=ds.attrs.get("sweep_wall_time_s"))
            else:
                summary.failed[cid] = _err(e)
                st.write_failure(cid, {"case": cid, "error": _err(e), "traceback": _tb(e), "run": run_id,
                                       "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
                st.log("case-failed", run=run_id, case=cid, error=_err(e))
            if progress:
                progress(n, total, cid, e is None)
        summary.wall_s = time.perf_counter() - t0
        st.log("run-end", run=run_id, done=summary.done, failed=len(summary.failed), wall_s=summary.wall_s)
        return summary
    finally:
        st.unlock()
