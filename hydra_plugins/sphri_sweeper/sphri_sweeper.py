"""``hydra/sweeper=sphri``: Hydra's basic sweeper, plus a sweep that ends cleanly.

- Every job's config is composed and validated (Hydra's types, then
  :func:`sphri.config.validate`) before any job starts; all failing points
  are listed and the sweep exits with status 2 without starting a job or
  opening a parent run.
- The MLflow parent run is found or created after that
  (:func:`sphri.tracking.parent.open_parent`) and always ended
  (:func:`~sphri.tracking.parent.close_parent`): FINISHED, FAILED when a job
  failed or the sweep raised, KILLED on SIGINT/SIGTERM.
- With the environment variable ``SPHRI_VALIDATE_ONLY=1`` (what
  ``sphri validate -m ...`` sets) the sweep stops after that
  check: it prints how many jobs it checked and exits 0, or 2 with the
  failing points, without running anything.
- A sweep with a failed job exits with status 1 naming the jobs; a killed
  one with 128 + the signal number. The signal handler raises in the main
  thread and also records the signal: should library code swallow the
  exception, the next job (in-process launchers) refuses to start.

It subclasses :class:`~hydra._internal.core_plugins.basic_sweeper.BasicSweeper`
(same ``max_batch_size`` and ``params``) and works with any launcher.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser

from sphri.tracking.parent import KILLED, SweepKilled

log = logging.getLogger(__name__)

#: Environment variable: validate every job of the sweep, then stop (``sphri validate -m``).
VALIDATE_ONLY = "SPHRI_VALIDATE_ONLY"
#: Jobs listed by a validate-only sweep.
MAX_LISTED = 12


#: Seconds between a deferred signal's retries (see :func:`_raise_killed`).
RETRY_S = 0.05


def _importing(frame: Any) -> bool:
    """Whether ``frame`` runs inside an import (a module's body, an extension module's init)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _resend(signum: int) -> None:
    if signal.getsignal(signum) is _raise_killed:  # the sweep has not ended meanwhile
        os.kill(os.getpid(), signum)


def _raise_killed(signum: int, frame: Any) -> None:
    """SIGTERM/SIGINT during a sweep: raise :class:`SweepKilled` in the main thread.

    Not inside an import: an exception raised while an extension module initialises can abort the
    process (seen in CI: a SIGTERM landing in ``import trimesh``, inside manifold3d's init, ended the
    sweep with SIGABRT instead of 128 + 15 and left its parent run RUNNING). There the signal is
    recorded and sent again every ``RETRY_S`` seconds until it lands outside any import."""
    if signum not in KILLED:
        KILLED.append(signum)  # sticky: the next job refuses to start should this exception be swallowed
    if _importing(frame):
        retry = threading.Timer(RETRY_S, _resend, (signum,))
        retry.daemon = True
        retry.start()
        return
    raise SweepKilled(KILLED[0])


def killed_by(exc: BaseException) -> int | None:
    """The signal number that ended the sweep when ``exc`` escaped it, else None (a real failure).

    A signal's :class:`SweepKilled` raised inside library code (OmegaConf, Hydra's job composition)
    can be replaced while unwinding by an unrelated error from the half-finished call; once a signal
    was received (``KILLED``), the sweep was killed whatever exception surfaced."""
    if isinstance(exc, SweepKilled):
        return exc.signum
    if KILLED:
        return KILLED[0]
    if isinstance(exc, KeyboardInterrupt):
        return int(signal.SIGINT)
    return None


def _empty_sweeps(arguments: Sequence[str]) -> list[str]:
    """The sweep overrides among ``arguments`` that give no value (``range(5,5)``, an empty choice)."""
    empty = []
    for o in OverridesParser.create().parse_overrides(list(arguments)):
        try:
            if o.is_sweep_override() and not list(o.sweep_string_iterator()):
                empty.append(str(o.input_line))
        except Exception:  # a glob: expanded (and checked) before the sweep
            continue
    return empty


def _container(node: Any) -> dict:
    """``node`` (a DictConfig) as a plain dict, unresolved."""
    from omegaconf import OmegaConf

    out = OmegaConf.to_container(node, resolve=False)
    if not isinstance(out, dict):
        raise TypeError(f"expected a mapping in the sweep's config, got {type(out).__name__}")
    return out


class SkippingLauncher:
    """A launcher that hands its wrapped launcher only the jobs not yet finished (each contiguous run
    of them with its own job numbers, so folders and numbers stay those of the whole sweep) and
    answers the finished ones itself."""

    def __init__(self, launcher: Any, finished: dict[int, tuple[str, list[str]]]) -> None:
        self.launcher = launcher
        self.finished = finished

    def __getattr__(self, name: str) -> Any:
        return getattr(self.launcher, name)

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Any:
        from hydra.core.utils import JobReturn, JobStatus

        results: list[Any] = []
        run: list[Sequence[str]] = []
        start = initial_job_idx
        for k, job in enumerate(job_overrides):
            idx = initial_job_idx + k
            if idx not in self.finished:
                if not run:
                    start = idx
                run.append(job)
                continue
            if run:
                results += list(self.launcher.launch(run, initial_job_idx=start))
                run = []
            done = JobReturn(overrides=list(job), status=JobStatus.COMPLETED)
            done.return_value = {"run_id": self.finished[idx][0], "skipped": True}
            results.append(done)
        if run:
            results += list(self.launcher.launch(run, initial_job_idx=start))
        return results


class SphriSweeper(BasicSweeper):
    """See the module docstring."""

    def job_overrides(self, arguments: Sequence[str]) -> tuple[list[str], list[list[str]]]:
        """``(the sweep's overrides, every job's overrides)``, as the basic sweeper expands them."""
        assert self.hydra_context is not None
        from sphri.config import normalize_overrides

        params_conf = normalize_overrides([*self._parse_config(), *arguments])  # encoder.res is layout.res
        parser = OverridesParser.create(config_loader=self.hydra_context.config_loader)
        batches = self.split_arguments(parser.parse_overrides(params_conf), self.max_batch_size)
        return params_conf, [list(job) for batch in batches for job in batch]

    def invalid_points(self, jobs: Sequence[Sequence[str]]) -> list[tuple[int, list[str], str]]:
        """``(job number, overrides, error)`` of every job whose config does not compose or validate."""
        from sphri.config import ConfigError, _explain, check_inputs, validate
        from sphri.pipeline import chain_region
        from sphri.progress import bar

        assert self.hydra_context is not None and self.config is not None
        bad = []
        self._configs = {}
        compose_job = self.job_composer()
        with bar(len(jobs), "checking the sweep's jobs", unit="job") as shown:
            for i, job in enumerate(jobs):
                try:
                    cfg = compose_job(list(job))
                    self._configs[i] = cfg
                    validate(cfg)
                    chain_region(cfg)
                    check_inputs(cfg)
                except ConfigError as exc:
                    bad.append((i, list(job), str(exc)))
                except Exception as exc:  # Hydra's composition and type errors (the cause says which value)
                    bad.append((i, list(job), _explain(exc)))  # the key's own error, found in the chain
                shown.update(1)
        return bad

    def job_composer(self) -> Any:
        """``compose(job overrides) -> the job's config``, as Hydra's ``load_sweep_config`` composes it.

        Composing is the cost of checking a sweep (about 0.3 s a job). The jobs of a sweep mostly
        differ in plain values (``layout.res=18``), so each distinct set of the other overrides
        (group choices such as ``sensitivity=noise0``, additions ``+key=``, deletions ``~key``) is
        composed once by Hydra, and a job's plain value overrides are then set on a copy of that
        config as Hydra sets them: the split and the setting are :func:`sphri.config.split_overrides`
        and :func:`sphri.config.set_values`, which :func:`sphri.config.compose` uses too (the same
        one-line errors). ``tests/test_sweeps_store.py`` checks that both give the same configs on
        the experiments' sweeps."""
        import copy

        from sphri.config import set_values, split_overrides

        assert self.hydra_context is not None and self.config is not None
        loader = self.hydra_context.config_loader
        config = self.config
        groups: dict[str, bool] = {}
        bases: dict[tuple[str, ...], Any] = {}

        def is_group(key: str) -> bool:
            if key not in groups:
                try:
                    groups[key] = bool(loader.get_group_options(key))
                except Exception:  # not a group name Hydra can list
                    groups[key] = False
            return groups[key]

        def compose(job: list[str]) -> Any:
            split = split_overrides(job, is_group)
            if split is None:  # Hydra's parser refuses an override: Hydra's composition says which
                return loader.load_sweep_config(config, list(job))
            structural, plain = split
            rest = tuple(structural)
            if rest not in bases:
                bases[rest] = loader.load_sweep_config(config, list(rest))
            cfg = copy.deepcopy(bases[rest])
            set_values(cfg, plain)
            return cfg

        return compose

    def finished_jobs(self, jobs: Sequence[Sequence[str]]) -> dict[int, tuple[str, list[str]]]:
        """``{job number: (finished MLflow run id, swept overrides)}`` of the jobs whose config already
        has a FINISHED run (``resume=true``, tracking on): their status is written here and no worker
        starts for them, so a rerun of a finished sweep is answered by this process alone. Done only
        where a job's folder is the default ``<sweep dir>/<job number>``; elsewhere the jobs skip
        themselves (the same check, in each job)."""
        from omegaconf import open_dict

        from sphri.pipeline import build, config_hash
        from sphri.tracking.parent import progress_line, write_status

        assert self.config is not None
        if (
            not self.config.get("resume")
            or not self.config.tracking.enabled
            or _container(self.config.hydra.sweep).get("subdir") != "${hydra.job.num}"
        ):
            return {}
        tracker = build(self.config.tracking)
        sweep_dir = Path(self.config.hydra.sweep.dir)
        out = {}
        for i, job in enumerate(jobs):
            cfg = self._configs.get(i)
            if cfg is None:
                continue
            cfg = cfg.copy()
            with open_dict(cfg):
                cfg.pop("hydra", None)
            done = tracker.find_finished(cfg.output_dir, config_hash(cfg))
            if done:
                swept = [o for o in job if not o.lstrip("+~").startswith("hydra")]
                out[i] = (done, swept)
                write_status(sweep_dir / str(i), i, "SKIPPED", None, done, overrides=swept)
                print(
                    progress_line(
                        sweep_dir,
                        i,
                        f"({' '.join(swept)}) skipped: MLflow run {done} already finished with this config",
                    ),
                    flush=True,
                )
        return out

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        """Already done for every job before the sweep started (:meth:`invalid_points`)."""

    def sweep(self, arguments: list[str]) -> Any:
        from sphri.tracking.parent import SweepDirInUse, claim_sweep_dir

        assert self.config is not None
        overrides, jobs = self.job_overrides(arguments)
        if not jobs:  # e.g. range(5,5): nothing to run is a mistake, not a finished sweep
            print(
                f"sphri: invalid sweep: {' '.join(_empty_sweeps(arguments)) or ' '.join(arguments)} sweeps no "
                "value; no job was started",
                file=sys.stderr,
            )
            sys.exit(2)
        bad = self.invalid_points(jobs)
        if bad:
            lines = [f"sphri: invalid sweep: {len(bad)} of {len(jobs)} points fail validation; no job was started"]
            lines += [f"  job #{i} ({' '.join(ov)}): {err}" for i, ov, err in bad]
            log.debug("\n".join(lines))
            print("\n".join(lines), file=sys.stderr)
            sys.exit(2)
        if os.environ.get(VALIDATE_ONLY) == "1":
            print(f"sweep OK: all {len(jobs)} jobs compose and validate (nothing was run)")
            for i, job in enumerate(jobs[:MAX_LISTED]):
                print(f"  job #{i}: {' '.join(job)}")
            if len(jobs) > MAX_LISTED:
                print(f"  ... and {len(jobs) - MAX_LISTED} more")
            sys.exit(0)
        try:  # one sweep per folder: not one running now, nor another's jobs left there
            claim = claim_sweep_dir(self.config.hydra.sweep.dir, jobs, self.config.output_dir)
        except SweepDirInUse as exc:
            print(f"sphri: {exc}", file=sys.stderr)
            sys.exit(1)
        try:
            return self._sweep_claimed(arguments, overrides, jobs)
        finally:
            claim.release()

    def _sweep_claimed(self, arguments: list[str], overrides: list[str], jobs: list[list[str]]) -> Any:
        """The sweep, once its folder is claimed: parent run, jobs, summary."""
        from sphri.tracking.parent import close_parent, open_parent, start_sweep_file

        assert self.config is not None
        start_sweep_file(self.config.hydra.sweep.dir, len(jobs), jobs, self.config.output_dir)
        KILLED.clear()
        # handlers first: a signal while the parent run opens still ends it KILLED, not RUNNING
        previous = {sig: signal.signal(sig, _raise_killed) for sig in (signal.SIGTERM, signal.SIGINT)}
        interrupted = None
        try:
            open_parent(self.config, overrides)
            finished = self.finished_jobs(jobs)  # answered here: no worker starts for them
            if finished:
                self.launcher = SkippingLauncher(self.launcher, finished)  # type: ignore[assignment]  # Hydra types it Launcher; ours duck-types launch()
            returns = super().sweep(arguments)
            if KILLED:  # the signal's exception was swallowed inside a job; the next job stopped the sweep
                raise SweepKilled(KILLED[0])
        except BaseException as exc:
            killed = killed_by(exc)
            if killed is None:
                interrupted = "FAILED"
                raise
            interrupted, code, returns = "KILLED", 128 + killed, None
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            status, failed = close_parent(self.config, interrupted)
        if interrupted == "KILLED":
            print(
                "sphri: sweep killed; its MLflow parent run is marked KILLED (re-run the same command to resume)",
                file=sys.stderr,
            )
            sys.exit(code)
        if failed:
            print(
                f"sphri: sweep FAILED: {len(failed)} job(s) failed: " + ", ".join(f"#{s['job']}" for s in failed),
                file=sys.stderr,
            )
            sys.exit(1)
        return returns
