"""``python -m sphri``: run one experiment job, or a sweep with ``-m``.

Examples::

    python -m sphri                                  # built-in defaults (robot=reachy)
    python -m sphri +robot=reachy layout.res=18     # the paper's resolution
    python -m sphri -m +robot=reachy layout.res=4,8,18
    python -m sphri +debug=fast                      # seconds-long smoke run

Each job validates its config before any stage runs, runs the pipeline
(stages cached under ``outputs/cache``), logs one MLflow run and prints a
one-screen summary. In a multirun (``hydra/sweeper=sphri``), every job's
config is validated before any job starts, a failing job is recorded as
FAILED in MLflow and the sweep goes on, then exits non-zero naming it; the
sweep's parent run always ends (FINISHED, FAILED or KILLED).
"""

from __future__ import annotations

import logging
import os
import sys
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from sphri.config import (
    CONF_DIR,
    ConfigError,
    check_choices,
    check_inputs,
    check_output_dir,
    compose,
    normalize_overrides,
    register_schemas,
    resolved_setting,
    validate,
)
from sphri.errors import report, take_verbose_flag, verbose_requested

log = logging.getLogger("sphri")


def limit_threads(n: int) -> None:
    """Cap BLAS/OpenMP/numba/torch threads and sphri's own (parallel sweep jobs share the cores).

    numba and torch are capped here only where they are imported already; otherwise each sizes its pool from
    the variables set here when the job first imports it, so a job that never uses torch (a Random Forest's)
    does not import it (what that saves a sweep: docs/BENCHMARKS.md)."""
    from threadpoolctl import threadpool_limits  # scikit-learn's dependency, imported by sphri.evaluate.cv too

    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "SPHRI_THREADS"):
        os.environ[var] = str(n)
    threadpool_limits(n)
    numba = sys.modules.get("numba")
    if numba is not None:  # its pool was sized at import: cap it (within that size)
        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n)


def passive_openmp() -> None:
    """OpenMP threads that wait for work sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE``), unless the
    environment sets a policy: on cores other processes share, spinning torch threads cost the CNN-GRU several
    times the CPU per training step for the same numbers (docs/BENCHMARKS.md). The OpenMP runtime reads the
    variable when torch loads, so this runs before any job imports torch; fold processes inherit it."""
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def quiet_console() -> None:
    """Raise the root logger's console handlers to WARNING: a sweep's job logs its stages to its log
    file only (``hydra.verbose=true`` or ``--verbose`` keeps them on the console)."""
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler):
            handler.setLevel(logging.WARNING)


@dataclass
class _Job:
    """Where a job runs and how it reports: its folder, its place in a sweep, the overrides swept."""

    dir: Path
    choices: dict[str, str]
    multirun: bool
    num: int
    parent: dict | None
    swept: list[str]
    sweep_dir: str
    log_file: Path
    t_start: float = field(default_factory=time.perf_counter)

    def say(self, what: str) -> None:
        """The sweep's console: one line per finished job."""
        from sphri.tracking.parent import progress_line

        print(progress_line(self.sweep_dir, self.num, what), flush=True)

    @property
    def label(self) -> str:
        return f"({' '.join(self.swept)})"


def _job(cfg: DictConfig) -> _Job:
    """This job as Hydra runs it; a sweep's job shares the cores and the console (thread caps, one
    progress display, a quiet console: its log file keeps everything)."""
    from sphri.tracking.parent import read_parent

    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    job = _Job(
        dir=Path(hc.runtime.output_dir),
        choices={k: v for k, v in hc.runtime.choices.items() if v is not None and not k.startswith("hydra")},
        multirun=multirun,
        num=int(hc.job.num) if multirun else 0,
        parent=read_parent(hc.sweep.dir) if multirun else None,
        swept=[o for o in (hc.overrides.task if multirun else []) if not o.lstrip("+~").startswith("hydra")],
        sweep_dir=str(hc.sweep.dir),
        log_file=Path(hc.runtime.output_dir) / f"{hc.job.name}.log",
    )
    if multirun:
        cores = os.cpu_count() or 1
        n_jobs = int(hc.launcher.get("n_jobs", 1) or 1)
        n_jobs = cores if n_jobs < 0 else n_jobs
        if n_jobs > 1:
            limit_threads(max(1, cores // n_jobs))
        if "progress" in cfg.get("cv", {}):  # one progress display for the sweep, not a bar per job (runtime setting)
            OmegaConf.update(cfg, "cv.progress", False, force_add=False)
        if not (hc.verbose or verbose_requested()):
            quiet_console()
    return job


def _open_tracker(cfg: DictConfig) -> Any:
    """Check the config and its inputs, then open the tracker (its store created or refused before computing)."""
    from sphri import pipeline

    validate(cfg)
    pipeline.chain_region(cfg)
    check_inputs(cfg)
    tracker = pipeline.build(cfg.tracking)
    if tracker.enabled:
        tracker.client(cfg.output_dir)  # create the store (under a lock) or refuse a broken one
    return tracker


def _finished_already(cfg: DictConfig, job: _Job, tracker: Any) -> dict | None:
    """A sweep's job whose config a finished MLflow run holds (``resume``): recorded SKIPPED, not run."""
    from sphri import pipeline
    from sphri.tracking.parent import write_status

    if not (job.multirun and cfg.resume and tracker.enabled):
        return None
    done = tracker.find_finished(cfg.output_dir, pipeline.config_hash(cfg))
    if not done:
        return None
    log.info("job %d skipped: MLflow run %s already finished with this config", job.num, done)
    write_status(job.dir, job.num, "SKIPPED", None, done, overrides=job.swept)
    job.say(f"{job.label} skipped: MLflow run {done} already finished with this config")
    return {"run_id": done, "skipped": True}


def _failed(cfg: DictConfig, job: _Job, tracker: Any, exc: Exception) -> None:
    """Record a job that raised ``exc`` (called while it is handled): its MLflow run when one can be
    recorded, its status file; a sweep goes on (one console line), a single job exits with one line or
    re-raises an unexpected error."""
    from sphri import pipeline
    from sphri.tracking.parent import write_status
    from sphri.tracking.store import StoreError

    error = f"{type(exc).__name__}: {exc}"
    if tracker is None:
        try:
            tracker = pipeline.build(cfg.tracking)
        except Exception:  # the tracking config itself is broken
            tracker = None
    broken = isinstance(exc, StoreError)  # broken, busy or not a store: no run can be recorded in it
    # An invalid config is not a run: it makes no MLflow run (only the job's status file says so).
    recorded = tracker is not None and tracker.enabled and not broken and not isinstance(exc, ConfigError)
    run_id = tracker.log_failure(cfg, exc, job.dir, job.parent, job.choices) if recorded else None
    write_status(job.dir, job.num, "FAILED", error, run_id, overrides=job.swept)
    if job.multirun:  # one line on the console; the traceback in the job's log file
        log.error("job %d FAILED: %s", job.num, error)
        log.info("traceback of job %d:\n%s", job.num, traceback.format_exc())
        job.say(f"{job.label} FAILED: {' '.join(error.split())[:300]}; log: {job.log_file}")
        return
    if broken:
        log.error("%s", exc)
        print(f"sphri: {exc}", file=sys.stderr)
        sys.exit(1)
    code = report("sphri", exc)  # one line for expected errors; traceback with --verbose / HYDRA_FULL_ERROR=1
    if code is not None:
        sys.exit(code)
    raise exc


def _log(cfg: DictConfig, job: _Job, tracker: Any, result: Any) -> tuple[str | None, int, str]:
    """``(run id, reruns, model note)``: the job's MLflow run (a single job that repeats a finished one is
    tagged as a rerun of it) and its model where asked."""
    run_id, reruns, model_note = None, 0, ""
    if tracker.enabled and not job.multirun:
        # the same experiment again (same config hash, runtime settings aside): recorded once, on its first run
        run_id = tracker.find_finished(cfg.output_dir, result.config_hash)
        reruns = tracker.mark_rerun(cfg.output_dir, run_id, job.dir) if run_id else 0
    if tracker.enabled and run_id is None:
        run_id = tracker.log_job(cfg, result, job.dir, job.parent, choices=job.choices)
        # log_model None (the default): a single job logs its model, a sweep's jobs do not
        if tracker.log_model or (tracker.log_model is None and not job.multirun):
            model_note = _log_model(cfg, tracker, run_id)
    elif tracker.enabled and tracker.log_model and run_id is not None:  # asked for explicitly (true); run found
        # already recorded: log the model into that run unless it holds one (never silently nothing)
        held = tracker.logged_models(cfg.output_dir, run_id)
        model_note = f"model already logged in that run: {held[0]}" if held else _log_model(cfg, tracker, run_id)
    return run_id, reruns, model_note


def _print(cfg: DictConfig, job: _Job, tracker: Any, result: Any, logged: tuple[str | None, int, str]) -> dict:
    """Write the job's status and summary.txt; print its line (a sweep's job) or its summary box."""
    from sphri.tracking.mlflow_tracker import summary_text, ui_hint
    from sphri.tracking.parent import write_status

    run_id, reruns, model_note = logged
    summary = result.summary()
    from_cache = result.stages["evaluate"].source == "cache" if "evaluate" in result.stages else False
    write_status(
        job.dir,
        job.num,
        "FINISHED",
        None,
        run_id,
        overrides=job.swept,
        accuracy=summary.get("accuracy_mean"),
        macro_f1=summary.get("macro_f1_mean"),
        seconds=time.perf_counter() - job.t_start,
        from_cache=from_cache,
    )
    text = summary_text(result)
    (job.dir / "summary.txt").write_text(text + "\n")
    if job.multirun:  # the job's summary box is in its summary.txt; the sweep prints one line per job and a table
        job.say(
            f"{job.label} accuracy {summary.get('accuracy_mean', float('nan')):.3f}"
            + (" (from cache)" if from_cache else "")
            + f"; {job.dir / 'summary.txt'}"
        )
        return {"run_id": run_id, **summary}
    uri = tracker.resolve_uri(cfg.output_dir) if run_id else ""
    where = f"MLflow run {run_id} in {uri} (see it with `{ui_hint(uri)}`)" if run_id else "MLflow tracking disabled"
    if reruns:
        where = f"already recorded: {where}; tagged sphri.reruns={reruns}, no new run"
    if model_note:
        where += f"\nmodel       {model_note}"
    print("\n" + "=" * 78 + "\n" + text + f"\ntracking    {where}\njob dir     {job.dir}\n" + "=" * 78)
    return {"run_id": run_id, **summary}


def run_job(cfg: DictConfig) -> dict | None:
    """One job: check the config, run the chain, log it, print its summary (a sweep's job: one line)."""
    from sphri import pipeline
    from sphri.tracking.parent import stop_if_killed

    stop_if_killed()  # a serial sweep signalled during an earlier job starts no more jobs
    job = _job(cfg)
    tracker = None
    try:
        tracker = _open_tracker(cfg)
        skipped = _finished_already(cfg, job, tracker)
        if skipped is not None:
            return skipped
        result = pipeline.run(cfg)
    except Exception as exc:
        _failed(cfg, job, tracker, exc)
        return None
    return _print(cfg, job, tracker, result, _log(cfg, job, tracker, result))


def _log_model(cfg: DictConfig, tracker, run_id: str) -> str:
    """Fit the job's model on every participant and log it into ``run_id``; the line the summary prints."""
    from sphri.export.train import log_job_model

    t0 = time.perf_counter()
    uri = log_job_model(cfg, run_id, tracker.register_model)
    seconds = time.perf_counter() - t0
    log.info("logged the model (fit on every participant): %s in %.1f s", uri, seconds)
    return f"logged {uri} (fit on every participant, {seconds:.1f} s)"


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def _hydra_main(cfg: DictConfig) -> dict | None:
    return run_job(cfg)


def find_sweeper_plugin() -> None:
    """Make Hydra's plugin scan see ``hydra_plugins.sphri_sweeper``.

    Hydra finds plugins by walking ``hydra_plugins.__path__`` (a namespace package). A wheel puts
    the folder in site-packages, on that path; an editable install maps the module through its own
    finder instead, which that walk never sees, and one made before the plugin existed maps nothing.
    Either way the folder holding ``sphri_sweeper`` is added to the namespace's path.
    """
    import importlib.util

    import hydra_plugins

    spec = importlib.util.find_spec("hydra_plugins.sphri_sweeper")
    if spec is not None and spec.origin:
        here = Path(spec.origin).resolve().parent.parent
    else:
        here = Path(__file__).resolve().parent.parent / "hydra_plugins"
    if (here / "sphri_sweeper").is_dir() and str(here) not in [str(Path(p).resolve()) for p in hydra_plugins.__path__]:
        hydra_plugins.__path__.append(str(here))


def _fixed_overrides(args: list[str]) -> list[str] | None:
    """The overrides every job shares (a sweep's swept ones left out: its sweeper checks each job), for a
    composition check before Hydra's; None when a Hydra flag (``--cfg``, ``-sc``, ``--info``, ...) composes the
    config its own way. An override that does not parse is a :class:`ConfigError` naming it."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    if any(a.startswith("-") and a not in ("-m", "--multirun") for a in args):
        return None
    parser = OverridesParser.create()
    parsed = []
    for arg in (a for a in args if not a.startswith("-")):
        try:
            parsed += parser.parse_overrides([arg])
        except Exception as exc:  # Hydra's lexer and parser: a caret under the position, over several lines
            raise ConfigError(override_parse_error(arg, exc)) from None
    # Override.input_line is Optional, but parse_overrides sets it on every override it returns
    return [cast(str, o.input_line) for o in parsed if not o.is_sweep_override()]


def override_parse_error(arg: str, exc: BaseException) -> str:
    """One line for an override Hydra's grammar refuses, naming it (and a non-ASCII character in it)."""
    odd = next((c for c in arg if not c.isascii()), None)
    if odd is not None:
        key, sep, _ = arg.partition("=")
        hint = (
            "keys are ASCII names"
            if sep == "" or odd in key
            else f"quote a value holding one, e.g. {key}='{arg.partition('=')[2]}'"
        )
        return f"override {arg!r} does not parse: non-ASCII character {odd!r} at position {arg.index(odd)}; {hint}"
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return f"override {arg!r} does not parse ({first}); see https://hydra.cc/docs/advanced/override_grammar/basic"


def main() -> None:
    """Hydra's entry point: one job or a sweep (``sphri run``/``sphri sweep``, or ``python -m sphri``
    with overrides)."""
    passive_openmp()
    find_sweeper_plugin()
    # hydra-ray-launcher registers its own `ray` launcher schema; sphri's
    # conf/hydra/launcher/ray.yaml extends it on purpose.
    warnings.filterwarnings(
        "ignore", message=r"(?s).*'hydra/launcher/ray' is validated against ConfigStore schema", category=UserWarning
    )
    if any(a in ("--help", "-h") for a in sys.argv[1:]):
        from sphri.cli import help_text
        from sphri.command import print_help

        print_help(help_text())  # sphri's own help: Hydra's would print every schema entry and the whole config
        return
    register_schemas()
    sys.argv = [sys.argv[0], *normalize_overrides(take_verbose_flag(sys.argv[1:]))]
    try:
        check_choices(sys.argv[1:])  # a misspelt component: one line with the real options, before Hydra
        fixed = _fixed_overrides(sys.argv[1:])
        if fixed is not None:
            # an unknown key or a value of the wrong type: sphri's one line, before Hydra's own message
            # Hydra makes the run folder inside output_dir before any check of ours
            check_output_dir(resolved_setting(compose(fixed, check=False), "output_dir"))
    except ConfigError as exc:
        print(f"sphri: invalid config: {exc}", file=sys.stderr)
        sys.exit(2)
    _hydra_main()


def module_main() -> None:
    """``python -m sphri [VERB] ...`` is ``sphri VERB ...`` (:mod:`sphri.command`), but for ``--help`` first:
    the ``run`` verb's help (the config groups), not the list of verbs."""
    from sphri.command import main as dispatch

    args = sys.argv[1:]
    sys.exit(dispatch(["run", *args] if args[:1] in (["-h"], ["--help"]) else args))


if __name__ == "__main__":
    module_main()
