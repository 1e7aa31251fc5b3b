"""``terradyn sweep``: plan, run, status and collect sweeps (thin over terradyn.sweep)."""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer

from . import sub_app


def err(msg: str) -> None:
    """A message on stderr, never wrapped (paths and summaries stay greppable)."""
    from rich.console import Console

    Console(stderr=True, highlight=False, soft_wrap=True).print(msg)


def register(app: typer.Typer) -> None:
    sw = sub_app(name="sweep", no_args_is_help=True,
                     help="Sweeps of simulations from a TOML spec: local pool or Dask, resumable store.")

    @sw.command("plan")
    def plan(spec: Path = typer.Argument(..., help="Sweep spec (TOML)."),
             as_json: bool = typer.Option(False, "--json", help="Full resolved cases as JSON.")):
        """Show the cases of SPEC without running them (CSV on stdout: case_id + varied values)."""
        from .. import io
        from ..sweep import load

        io.check_input(spec, "spec")
        s = load(spec)
        if as_json:
            sys.stdout.write(json.dumps([c.to_json() for c in s.cases], indent=1) + "\n")
        else:
            import csv

            w = csv.writer(sys.stdout, lineterminator="\n")
            w.writerow(["case_id"] + s.varied)
            for c in s.cases:
                w.writerow([c.id] + [c.varied[p] for p in s.varied])
        err(f"{s.name}: {len(s.cases)} case(s), model {s.model}, varying {', '.join(s.varied) or 'nothing'}")

    @sw.command("run")
    def run(spec: Path = typer.Argument(..., help="Sweep spec (TOML)."),
            store: Optional[Path] = typer.Option(None, "--store", help="Store directory [default: NAME.sweep]."),
            scheduler: Optional[str] = typer.Option(
                None, "--scheduler", help="Dask scheduler address (tcp://host:8786); "
                                          "default: env TERRADYN_DASK_SCHEDULER, else a local pool."),
            workers: Optional[int] = typer.Option(None, "--workers", help="Local pool size [default: cores]; 0 = in this process."),
            retries: int = typer.Option(0, "--retries", help="Extra attempts of a case that raised (Dask)."),
            checkpoint_dir: Optional[Path] = typer.Option(
                None, "--checkpoint-dir", help="Where SPH cases keep resumable state [default: STORE/checkpoints; none on Dask]."),
            out: Optional[Path] = typer.Option(None, "--out", help="Collect into this NetCDF when all cases are done."),
            quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")):
        """Run the unfinished cases of SPEC into the store (rerun to resume)."""
        from .. import io
        from ..sweep import collect, load, run as run_sweep
        from ..sweep.execute import default_store
        from ..sweep.store import Store

        from ..errors import integer

        io.check_input(spec, "spec")
        io.check_output(out, "out", (".nc",))
        if workers is not None:
            integer("workers", workers, 0)
        integer("retries", retries, 0)
        s = load(spec)
        Store(store if store is not None else default_store(s)).claim(s)
        st_path = store if store is not None else default_store(s)
        io.check_writable(st_path, "store", directory=True)
        if checkpoint_dir is not None:
            io.check_writable(checkpoint_dir, "checkpoint-dir", directory=True)
        cb, bar = None, None
        if not quiet:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            bar = Progress(TextColumn(f"{s.name}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                           TimeRemainingColumn(), TextColumn("{task.fields[failed]}"),
                           console=Console(stderr=True), transient=False)
            task = bar.add_task("cases", total=len(s.cases), failed="")
            nfail = [0]

            def cb(n, total, cid, ok):
                nfail[0] += not ok
                bar.update(task, completed=n, failed=f"[red]{nfail[0]} failed" if nfail[0] else "")

            bar.start()
        try:
            summ = run_sweep(s, store, workers=workers, scheduler=scheduler, retries=retries,
                             checkpoint_dir=checkpoint_dir, progress=cb)
        finally:
            if bar is not None:
                bar.stop()
        err(f"{summ.store}: {summ.done} run, {summ.skipped} already done, {len(summ.failed)} failed, "
            f"of {summ.total} ({summ.executor}, {summ.wall_s:.1f} s)")
        for cid, e in summ.failed.items():
            from rich.markup import escape

            err(f"  [red]failed[/] {cid}: {escape(str(e))}")
        if summ.failed:
            err("rerun the same command to retry the failed cases")
            raise typer.Exit(1)
        if out is not None:
            collect(summ.store, out)
            err(f"wrote {out}")

    @sw.command("status")
    def status(store: Path = typer.Argument(..., help="Sweep store directory."),
               as_json: bool = typer.Option(False, "--json", help="Machine-readable status on stdout.")):
        """Counts of done / failed / pending cases and the failures' errors."""
        from ..sweep import status as st

        s = st(store)
        if as_json:
            sys.stdout.write(json.dumps(s, indent=1) + "\n")
            return
        sys.stdout.write(f"{s['name']} ({s['model']}): {s['done']}/{s['total']} done, {s['failed']} failed, "
                         f"{s['pending']} pending\n")
        for cid, f in s["failures"].items():
            sys.stdout.write(f"failed {cid}: {f.get('error', '')}\n")
        if s["orphans"]:
            sys.stdout.write(f"{len(s['orphans'])} finished case(s) no longer in the plan\n")

    @sw.command("collect")
    def collect_cmd(store: Path = typer.Argument(..., help="Sweep store directory."),
                    out: Path = typer.Option(..., "--out", help="Output NetCDF (.nc)."),
                    partial: bool = typer.Option(False, "--partial", help="Collect even if some cases are not done.")):
        """Stack the finished cases into one NetCDF with a `case` dimension (the training tensor)."""
        from .. import io
        from ..sweep import collect

        io.check_output(out, "out", (".nc",))
        ds = collect(store, out, partial=partial)
        err(f"wrote {out}: {ds.sizes['case']} cases x {dict((k, v) for k, v in ds.sizes.items() if k != 'case')}")

    app.add_typer(sw)
