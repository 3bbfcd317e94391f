"""Every Table I method prepares and runs; LLM methods ask only through the gate they name."""

from dataclasses import replace

import pytest

from globe.config import GlobeConfig
from globe.evaluation.methods import METHODS
from globe.evaluation.protocol import evaluate_days
from globe.evaluation.selection import Memo
from globe.reasoning.backends.base import Choice, LLMBackend


class LastCandidate(LLMBackend):
    """A scripted backend (test double): always the last listed candidate."""

    name = "scripted"

    def __init__(self) -> None:
        self.calls = 0

    def choose(self, context, candidates):
        self.calls += 1
        return Choice(candidates[-1], {c: float(i) for i, c in enumerate(candidates)})


@pytest.fixture(scope="module")
def small(households):
    return replace(households["A"], train=households["A"].train[:15], test=households["A"].test[:2])


@pytest.mark.parametrize("name", list(METHODS))
def test_method_prepares_and_runs(small, name):
    method, backend = METHODS[name], LastCandidate()
    cfg = GlobeConfig().with_overrides({"selection.folds": 3})
    prepared = method.prepare(small, cfg, backend if method.needs_llm else None, Memo())
    ev = evaluate_days(small, small.test, prepared.activity, prepared.chooser)
    assert ev.activity and ev.objects
    if name == "persistence":
        assert all(r.predicted == r.previous for r in ev.activity)
    asked = [r for r in ev.objects if r.asked]
    if method.needs_llm and name != "globe_routine":
        assert asked and backend.calls > 0  # the scripted answer is used, so the LLM path really ran
    if not method.needs_llm:
        assert not asked and backend.calls == 0
    if name == "globe_personal":
        assert prepared.chooser.examples == cfg.evaluation.personal_examples
