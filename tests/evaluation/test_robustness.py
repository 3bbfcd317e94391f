"""The robustness suite on a small generated HOMER-Noise (uniform proposals, no LLM)."""

from dataclasses import replace

import pytest

from globe.config import GlobeConfig
from globe.evaluation.published import DataScope
from globe.evaluation.robustness import run_suite
from globe.evaluation.robustness_results import write_robustness_results
from globe.noise.dataset import level_dir, read_manifest, write_level
from globe.noise.generate import propose
from globe.noise.proposals import UniformScorer


@pytest.fixture(scope="module")
def setup(households, tmp_path_factory):
    h = households["C"]
    small = replace(h, train=h.train[:10], test=h.test[:3])
    cfg = GlobeConfig().with_overrides({"noise.types": ("pet",), "noise.levels": (0.5, 1.0)})
    root = tmp_path_factory.mktemp("noise")
    proposals = {("C", "pet"): propose(small, "pet", UniformScorer(), seed=0, rate=1.0, temperature=2.0)}
    for level in (0.5, 1.0):
        write_level(root, [small], proposals, "pet", level)
    return cfg, small, root


def test_suite_scores_all_and_routine_events(setup, tmp_path):
    cfg, small, root = setup
    res = run_suite(cfg, [small], root, None, methods=("ngram",))
    write_robustness_results(tmp_path, res, cfg.noise, DataScope.of([small]))
    assert "SLaTe-PRO" not in (tmp_path / "robustness.md").read_text()  # a part of C is not HOMER+
    for name in ("robustness.csv", "consistency.csv", "ablation_train_level.csv", "robustness.md", "robustness.png",
                 "consistency_ngram_start_time.png", "ablation_train_level.png"):
        assert (tmp_path / name).is_file(), name
    clean = next(r for r in res.robustness if r["dataset"] == "clean")
    pet = next(r for r in res.robustness if r["dataset"] == "pet")
    injected_test = [m for m in read_manifest(level_dir(root, "pet", 1.0) / "manifest.csv") if m[1].startswith("test/")]
    assert pet["injected_events"] == len(injected_test) > 0
    assert pet["object_events"] == clean["object_events"] + pet["injected_events"]
    assert clean["injected_events"] == 0 and clean["object_f1"] == clean["object_f1_routine"]
    assert {(r["definition"], r["consistency"]) for r in res.consistency} == {
        (d, g) for d in ("start_time", "object_sequence") for g in ("more", "moderate", "less")}
    assert sorted(r["train_level"] for r in res.train_level) == [0.5, 1.0]


def test_noisy_copies_keep_the_clean_homes_alignment(setup, monkeypatch):
    """Which activity a movement is credited to is chosen on the clean home; its noisy copies are
    logged the same way and are not searched again (only their models are)."""
    import globe.evaluation.robustness as robustness
    from globe.evaluation.selection import Memo
    from globe.evaluation.tuning import chosen_alignment, tuned_models

    cfg, small, root = setup
    memo = Memo()
    fixed = robustness.clean_alignments(cfg, [small], ("routine",), memo)
    assert fixed == {"C": chosen_alignment(tuned_models(small, cfg, "routine", memo)[1], cfg)}
    seen = []
    real = robustness.precompute_selections

    def spy(config, households, families, memo, config_for=None):
        seen.extend((h, config_for(h, f) if config_for else config) for h in households for f in families
                    if f == "routine")
        return real(config, households, families, memo, config_for)

    monkeypatch.setattr(robustness, "precompute_selections", spy)
    run_suite(cfg, [small], root, None, methods=("routine",), memo=memo)
    noisy = [(h, c) for h, c in seen if h is not small]
    assert noisy and all(c.selection.alignments == (fixed["C"],) and c.sequences.alignment == fixed["C"]
                         for _, c in noisy)
    assert all(c is cfg for h, c in seen if h is small)  # the clean home itself is searched as configured


def test_only_the_routine_family_takes_the_clean_homes_alignment(setup, monkeypatch):
    """As if CV had chosen another alignment on the clean home: the routine rows of its noisy
    copies count and are scored with it; every other method counts and is scored as configured,
    as on the clean home."""
    import globe.assembly as assembly
    import globe.evaluation.robustness as robustness

    cfg, small, root = setup
    monkeypatch.setattr(robustness, "clean_alignments", lambda *a, **k: {"C": "current"})
    scored, method = set(), []
    real_dataset, real_eval = robustness.evaluate_dataset, robustness.evaluate_days

    def dataset(run_cfg, data, name, *args, **kwargs):
        method.append(name)
        return real_dataset(run_cfg, data, name, *args, **kwargs)

    def evaluate(h, *args, **kwargs):
        scored.add((method[-1], h is small, kwargs["alignment"]))
        return real_eval(h, *args, **kwargs)

    fitted, real_fit = set(), assembly.fit_household

    def fit(h, c, *args, **kwargs):
        if method:
            fitted.add((method[-1], h is small, c.sequences.alignment))
        return real_fit(h, c, *args, **kwargs)

    monkeypatch.setattr(robustness, "evaluate_dataset", dataset)
    monkeypatch.setattr(robustness, "evaluate_days", evaluate)
    monkeypatch.setattr(assembly, "fit_household", fit)
    run_suite(cfg, [small], root, None, methods=("ngram", "routine"))
    configured = cfg.sequences.alignment
    assert ("ngram", False, configured) in fitted and ("ngram", False, "current") not in fitted
    assert scored == {("ngram", True, configured), ("ngram", False, configured), ("routine", True, configured),
                      ("routine", False, "current")}
