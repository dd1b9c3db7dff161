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
  ``python -m sphri.cli validate -m ...`` sets) the sweep stops after that
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
from typing import Any, List, Sequence

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser

from sphri.tracking.parent import KILLED, SweepKilled

log = logging.getLogger(__name__)

#: Environment variable: validate every job of the sweep, then stop (``python -m sphri.cli validate -m``).
VALIDATE_ONLY = "SPHRI_VALIDATE_ONLY"
#: Jobs listed by a validate-only sweep.
MAX_LISTED = 12


def _raise_killed(signum: int, frame: Any) -> None:
    KILLED.append(signum)  # sticky: the next job refuses to start should this exception be swallowed
    raise SweepKilled(signum)


class SphriSweeper(BasicSweeper):
    """See the module docstring."""

    def job_overrides(self, arguments: Sequence[str]) -> tuple[list[str], list[list[str]]]:
        """``(the sweep's overrides, every job's overrides)``, as the basic sweeper expands them."""
        assert self.hydra_context is not None
        params_conf = [*self._parse_config(), *arguments]
        parser = OverridesParser.create(config_loader=self.hydra_context.config_loader)
        batches = self.split_arguments(parser.parse_overrides(params_conf), self.max_batch_size)
        return params_conf, [list(job) for batch in batches for job in batch]

    def invalid_points(self, jobs: Sequence[Sequence[str]]) -> list[tuple[int, list[str], str]]:
        """``(job number, overrides, error)`` of every job whose config does not compose or validate."""
        from sphri.config import ConfigError, _explain, check_inputs, validate
        from sphri.pipeline import chain_region

        assert self.hydra_context is not None and self.config is not None
        bad = []
        for i, job in enumerate(jobs):
            try:
                cfg = self.hydra_context.config_loader.load_sweep_config(self.config, list(job))
                validate(cfg)
                chain_region(cfg)
                check_inputs(cfg)
            except ConfigError as exc:
                bad.append((i, list(job), str(exc)))
            except Exception as exc:  # Hydra's composition and type errors (the cause says which value)
                bad.append((i, list(job), _explain(exc)))  # the key's own error, found in the chain
        return bad

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        """Already done for every job before the sweep started (:meth:`invalid_points`)."""

    def sweep(self, arguments: List[str]) -> Any:
        from sphri.tracking.parent import close_parent, open_parent, start_sweep_file

        assert self.config is not None
        overrides, jobs = self.job_overrides(arguments)
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
        start_sweep_file(self.config.hydra.sweep.dir, len(jobs))
        open_parent(self.config, overrides)
        KILLED.clear()
        previous = {sig: signal.signal(sig, _raise_killed) for sig in (signal.SIGTERM, signal.SIGINT)}
        interrupted = None
        try:
            returns = super().sweep(arguments)
            if KILLED:  # the signal's exception was swallowed inside a job; the next job stopped the sweep
                raise SweepKilled(KILLED[0])
        except (KeyboardInterrupt, SweepKilled) as exc:
            interrupted = "KILLED"
            code = 128 + (exc.signum if isinstance(exc, SweepKilled) else signal.SIGINT)
            returns = None
        except BaseException:
            interrupted = "FAILED"
            raise
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            status, failed = close_parent(self.config, interrupted)
        if interrupted == "KILLED":
            print("sphri: sweep killed; its MLflow parent run is marked KILLED (re-run the same command to resume)",
                  file=sys.stderr)
            sys.exit(code)
        if failed:
            print(f"sphri: sweep FAILED: {len(failed)} job(s) failed: "
                  + ", ".join(f"#{s['job']}" for s in failed), file=sys.stderr)
            sys.exit(1)
        return returns
