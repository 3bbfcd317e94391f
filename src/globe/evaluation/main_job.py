"""The main job (``globe reproduce``) and its parts (``globe evaluate``, ``globe robustness``).

Every experiment runs as a named stage. A stage is timed, logged with its elapsed time when it
ends (one line on the ``globe.stages`` logger, so progress shows in CI logs and under ``nohup``
where no progress bar can), and writes its results as soon as it ends, so an interrupted run
keeps every finished stage. The per-stage times go to ``stages.csv`` in the results folder.
The data is loaded once by the caller; the LLM backend is built once and shared by all stages.
"""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator, Sequence

from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Household
from globe.errors import ConfigError
from globe.evaluation import report
from globe.evaluation.experiments import run_methods
from globe.evaluation.methods import METHODS, families, with_baselines
from globe.evaluation.parallel import precompute_selections
from globe.evaluation.recognised import (
    ACTIVITIES,
    Recognised,
    recognise_households,
    scope_of,
    write_recognition,
)
from globe.evaluation.results import Table1Results, write_table1_results
from globe.evaluation.robustness import RobustnessResults, run_suite
from globe.evaluation.robustness_results import write_robustness_results
from globe.evaluation.selection import Memo
from globe.noise.dataset import generate_dataset, read_summary
from globe.reasoning.backends.base import LLMBackend

if TYPE_CHECKING:
    from globe.evaluation.anticipation import AnticipationResult
    from globe.evaluation.missing_labels import MissingLabelResults

log = logging.getLogger("globe.stages")

Progress = Callable[[str], None]


@dataclass(slots=True)
class Stages:
    """Times named stages; each finished stage is logged and appended to ``stages.csv``."""

    out_dir: Path | None = None
    progress: Progress | None = None
    times: list[dict] = field(default_factory=list)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        log.info("%s: started", name)
        if self.progress:
            self.progress(name)
        started = time.perf_counter()
        yield
        seconds = time.perf_counter() - started
        self.times.append({"stage": name, "seconds": round(seconds, 2)})
        log.info("%s: done in %.1f s", name, seconds)
        if self.out_dir is not None:
            rows = self.times + [{"stage": "total", "seconds": round(sum(t["seconds"] for t in self.times), 2)}]
            report.write_csv(self.out_dir / "stages.csv", rows, ["stage", "seconds"])

    def note(self, message: str) -> None:
        """A progress message inside a stage (shown on a terminal; not logged)."""
        if self.progress:
            self.progress(message)


def check_methods(methods: Sequence[str]) -> list[str]:
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ConfigError(f"unknown method {unknown[0]!r}; expected one of {', '.join(METHODS)}")
    if not methods:
        raise ConfigError(f"no method given; expected some of {', '.join(METHODS)}")
    return list(methods)


def backend_for(config: GlobeConfig, methods: Sequence[str] = ()) -> LLMBackend | None:
    """The configured LLM backend, or None when no listed method needs one."""
    if methods and not any(METHODS[m].needs_llm for m in methods):
        return None
    return assembly.llm_backend(config.llm)


def evaluate(config: GlobeConfig, households: Sequence[Household], methods: Sequence[str], out_dir: Path,
             backend: LLMBackend | None = None, stages: Stages | None = None,
             memo: Memo | None = None, objects_ahead: bool = False,
             activities: str = "annotated", activity_ahead: bool = True) -> Table1Results:
    """Table I rows for ``methods`` and the baselines (:func:`~globe.evaluation.methods.with_baselines`)
    on each household's test days and (with ``activity_ahead``) the activity ahead, written to ``out_dir``; with
    ``objects_ahead``, also the lookahead and fetch-policy tables of the households with objects
    (:func:`object_anticipation`, forecasting with those of ``methods`` it can, beside the
    baselines). ``memo`` (cross-validation results and fits) is filled and reused. With
    ``activities="recognised"`` the models are shown the test days' activities as recognised
    from each home's sensors (:mod:`globe.evaluation.recognised`; ``recognition.csv`` says how
    well) and a deployable row's next activity is what its session serves, every score still
    against the annotation."""
    methods = check_methods(methods)
    stages = stages or Stages(out_dir)
    memo = Memo() if memo is None else memo
    if activities not in ACTIVITIES:
        raise ConfigError(f"unknown activities {activities!r}; expected {' or '.join(ACTIVITIES)}")
    (out_dir / "recognition.csv").unlink(missing_ok=True)  # a folder written before says nothing stale
    recognised: list[Recognised] = []
    if activities == "recognised":
        with stages.stage("recognition: the test days' activities from the sensors (settings by cross-validation)"):
            recognised = recognise_households(config, households, memo=memo)
            households = [r.household for r in recognised]
            write_recognition(out_dir, recognised)
    needed = families([m for m in methods if backend is not None or not METHODS[m].needs_llm])
    if needed:
        with stages.stage("table1: model selection (cross-validation, in parallel)"):
            precompute_selections(config, households, needed, memo)
    runs = []
    for method in with_baselines(methods):
        with stages.stage(f"table1: {method}"):
            runs += run_methods(config, households, [method], backend, memo, recognised)
    scope = scope_of(households)
    for stale in ("activity_anticipation.csv", "next_activity.csv", "activity_anticipation.png"):
        (out_dir / stale).unlink(missing_ok=True)  # a folder written before says nothing stale
    if activity_ahead:
        with stages.stage("activity anticipation"):
            from globe.evaluation.activity_anticipation import run_activity_anticipation, write_activity_anticipation

            scores = run_activity_anticipation(config, households, memo)
            write_activity_anticipation(out_dir, scores, f"{scope.title} test days: the activity ahead")
    with stages.stage("table1: write results"):
        written = write_table1_results(out_dir, runs, config, scope, activities)
    with_objects = [h for h in households if h.objects and h.test]
    ahead = lookahead_config(config, methods) if objects_ahead and with_objects else None
    if ahead is not None:
        steps = {h.name: assembly.step_minutes(h, config) for h in with_objects}
        if len(set(steps.values())) > 1:  # tabled by minutes ahead: one step per table
            log.warning("no lookahead or fetch-policy tables: the homes with objects have different steps (%s); "
                        "evaluate them separately", ", ".join(f"{name} {step} min" for name, step in steps.items()))
        else:
            object_anticipation(ahead, with_objects, out_dir, stages, memo, recognised)
    return written


def robustness(config: GlobeConfig, households: Sequence[Household], noise_dir: Path, out_dir: Path,
               backend: LLMBackend | None = None, stages: Stages | None = None,
               memo: Memo | None = None) -> tuple[dict, RobustnessResults]:
    """HOMER-Noise (generated unless ``noise_dir`` already holds this configuration's) and the
    robustness suite, written to ``out_dir``. Returns the noise summary and the suite's rows.
    ``memo`` holds cross-validation results already computed (on the clean households, say)."""
    stages = stages or Stages(out_dir)
    written: dict = {}  # the noisy households just generated: the suite need not read them back
    with stages.stage("homer-noise"):
        summary = read_summary(noise_dir)
        if not _same_noise(summary, config):
            summary = generate_dataset(config.noise, households, noise_dir, assembly.noise_scorer(config), stages.note,
                                       written)
    assert summary is not None
    with stages.stage("robustness suite"):
        res = run_suite(config, households, noise_dir, backend, progress=stages.note, memo=memo,
                        loaded=written)
        write_robustness_results(out_dir, res, config.noise, scope_of(households))
    return summary, res


def _same_noise(summary: dict | None, config: GlobeConfig) -> bool:
    """Whether a generated dataset was made with this configuration (else it is made again)."""
    if summary is None:
        return False
    n = config.noise
    return (summary.get("seed") == n.seed and summary.get("rate") == n.rate
            and summary.get("temperature") == n.temperature and summary.get("levels") == list(n.levels)
            and set(summary.get("types", {})) == set(n.types)
            and summary.get("scorer", "").startswith("uniform") == (config.llm.backend == "none"))


LOOKAHEAD_METHODS = ("persistence", "ngram", "routine")
"""The Table I methods the lookahead forecasts with (their activity models)."""


def object_anticipation(config: GlobeConfig, households: Sequence[Household], out_dir: Path,
                        stages: Stages | None = None, memo: Memo | None = None,
                        recognised: Sequence[Recognised] = ()) -> "AnticipationResult":
    """Lookahead (SLaTe-PRO's relocation metric) and the fetch policy on the households' test
    days, written to ``out_dir``, for the methods of ``config.lookahead.methods``. ``memo``
    shares the cross-validations already run; a household among ``recognised`` has its fetches
    decided by a session told its sensors and no label."""
    from globe.evaluation.anticipation import run_anticipation, write_anticipation_results

    stages = stages or Stages(out_dir)
    with stages.stage("anticipation: lookahead and fetch policy"):
        ahead = run_anticipation(config, households, progress=stages.note, memo=memo, recognised=recognised)
        write_anticipation_results(out_dir, ahead, scope_of(households))
    return ahead


def lookahead_config(config: GlobeConfig, methods: Sequence[str]) -> GlobeConfig | None:
    """``config`` with the lookahead forecasting with those of ``methods`` it can (persistence
    always, as the baseline row), or None when none can."""
    chosen = [m for m in LOOKAHEAD_METHODS if m in methods or m == "persistence"]
    if chosen == ["persistence"] and "persistence" not in methods:
        return None
    return config.with_overrides({"lookahead.methods": chosen})


def anticipation(config: GlobeConfig, households: Sequence[Household], out_dir: Path, stages: Stages | None = None,
                 memo: Memo | None = None) -> tuple["AnticipationResult", "MissingLabelResults"]:
    """Lookahead, the fetch policy (:func:`object_anticipation`), and prediction with missing
    activity labels, written to ``out_dir``. ``memo`` shares the main job's cross-validations."""
    from globe.evaluation.missing_labels import run_missing_labels, write_missing_label_results

    stages = stages or Stages(out_dir)
    memo = Memo() if memo is None else memo
    ahead = object_anticipation(config, households, out_dir, stages, memo)
    with stages.stage("anticipation: missing activity labels"):
        missing = run_missing_labels(config, households, progress=stages.note, memo=memo)
        write_missing_label_results(out_dir, missing.rows, missing.selection_rows)
    return ahead, missing


@dataclass(slots=True)
class MainJobResults:
    table1: Table1Results
    noise_summary: dict | None
    robustness: RobustnessResults | None
    anticipation: "AnticipationResult | None"
    missing_labels: "MissingLabelResults | None"
    stages: list[dict]


def reproduce(config: GlobeConfig, households: Sequence[Household], out_dir: Path, *, with_robustness: bool = True,
              with_anticipation: bool = True, progress: Progress | None = None) -> MainJobResults:
    """Every experiment on the given households, into ``out_dir`` (see the module doc)."""
    stages = Stages(out_dir, progress)
    with stages.stage("load LLM"):
        backend = backend_for(config, config.evaluation.methods)
    memo = Memo()
    table1 = evaluate(config, households, config.evaluation.methods, out_dir, backend, stages, memo)
    summary, res = None, None
    if with_robustness:
        summary, res = robustness(config, households, out_dir / "homer_noise", out_dir / "robustness", backend, stages,
                                  memo)
    ahead, missing = anticipation(config, households, out_dir, stages, memo) if with_anticipation else (None, None)
    return MainJobResults(table1, summary, res, ahead, missing, stages.times)
