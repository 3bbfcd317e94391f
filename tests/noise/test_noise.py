"""HOMER-Noise: valid movements only, nested levels, loadable output, manifest == difference."""

from dataclasses import replace

import pytest

from globe.data.csv_logs import load_household
from globe.noise.dataset import level_dir, read_manifest, summary, write_level
from globe.noise.generate import propose
from globe.noise.proposals import LLMScorer, UniformScorer
from globe.noise.rules import CLOSED, HIGH, HomeRules
from globe.sequences.movements import extract_movements

LEVELS = (0.25, 0.5, 1.0)


@pytest.fixture(scope="module")
def small(households):
    """Household A with 6 training and 2 test days (keeps the test fast)."""
    h = households["A"]
    return replace(h, train=h.train[:6], test=h.test[:2])


@pytest.fixture(scope="module")
def proposals(small, seed):
    return {(small.name, t): propose(small, t, UniformScorer(), seed=seed, rate=1.0, temperature=2.0)
            for t in ("person", "pet", "toddler")}


@pytest.fixture(scope="module")
def written(small, proposals, tmp_path_factory):
    root = tmp_path_factory.mktemp("noise")
    for t in ("person", "pet", "toddler"):
        for level in LEVELS:
            write_level(root, [small], proposals, t, level)
    return root


def test_every_written_movement_is_physically_valid(small, proposals):
    rules = HomeRules(small)
    days = {d.name: d for d in small.train + small.test}
    for (_, noise_type), props in proposals.items():
        assert props.injections, noise_type
        for inj in props.injections:
            before = dict(zip(small.objects, days[inj.day].locations[inj.step - 1]))
            assert inj.source == before[inj.obj] != inj.target
            assert inj.target in small.locations and inj.obj in small.objects
            assert rules.valid(noise_type, inj.obj, inj.source, inj.target, before) is None
            under = rules.support(inj.source, before)
            support = rules.cls[under]
            if noise_type == "pet":
                assert support not in CLOSED and support not in HIGH
                assert rules.category[inj.target] == "Rooms" or rules.room_of(inj.target) == rules.room_of(under)
            if noise_type == "toddler":
                assert support not in HIGH and rules.cls[inj.target] not in HIGH


def test_invalid_proposals_are_rejected_by_the_rules(small):
    rules = HomeRules(small)
    before = dict(zip(small.objects, small.train[0].locations[0]))
    milk_place = before["milk"]  # in the fridge at 06:00
    assert rules.cls[milk_place] == "fridge"
    room = rules.room_of(rules.support(milk_place, before))
    assert rules.valid("pet", "milk", milk_place, room, before) == "source out of reach"
    assert rules.valid("person", "milk", milk_place, milk_place, before) == "already there"
    assert rules.valid("person", "milk", milk_place, "attic#9", before) == "unknown destination"
    assert rules.valid("person", "unicorn", milk_place, room, before) == "unknown object"


def test_levels_nest(proposals):
    for props in proposals.values():
        sets = [set(props.at_level(lv)) for lv in LEVELS]
        assert sets[0] <= sets[1] <= sets[2]
        assert len(sets[0]) < len(sets[2])


def test_output_loads_with_the_normal_loader_and_manifest_matches_the_difference(small, written):
    for t in ("person", "pet", "toddler"):
        for level in LEVELS:
            folder = level_dir(written, t, level)
            noisy = load_household(folder, "A")  # the ordinary loader, unchanged
            manifest = read_manifest(folder / "manifest.csv")
            clean_days = {d.name: d for d in small.train + small.test}
            diff = set()
            for day in noisy.train + noisy.test:
                clean = {(e.step, e.obj) for e in extract_movements(clean_days[day.name], small.objects)}
                moved = {(e.step, e.obj) for e in extract_movements(day, small.objects)}
                assert clean <= moved  # no routine movement is lost
                diff |= {("A", day.name, s, o) for s, o in moved - clean}
            assert diff == manifest, (t, level)


def test_households_kept_at_writing_are_what_the_loader_reads_back(small, proposals, tmp_path):
    """The suite uses the households generation kept instead of parsing the files again: they
    must be the same data, day by day."""
    from globe.noise.dataset import noisy_dataset

    kept: dict = {}
    for t in ("person", "pet"):
        for level in LEVELS:
            write_level(tmp_path, [small], proposals, t, level, kept)
    assert len(kept) == 2 * len(LEVELS)
    for (folder, name), noisy in kept.items():
        read = load_household(folder, name)
        assert (read.name, read.nodes, read.objects) == (noisy.name, noisy.nodes, noisy.objects)
        for a, b in zip(read.train + read.test, noisy.train + noisy.test, strict=True):
            assert (a.name, a.minutes, a.activities, a.locations) == (b.name, b.minutes, b.activities, b.locations)
    from_memory = noisy_dataset(tmp_path, "pet", 0.5, 1.0, ["A"], dict(kept))
    from_disk = noisy_dataset(tmp_path, "pet", 0.5, 1.0, ["A"])
    assert from_memory.injected == from_disk.injected
    assert [d.locations for d in from_memory.households[0].test] == [d.locations for d in from_disk.households[0].test]


def test_generation_is_deterministic(small, proposals, seed):
    again = propose(small, "toddler", UniformScorer(), seed=seed, rate=1.0, temperature=2.0)
    assert again.injections == proposals[("A", "toddler")].injections
    other = propose(small, "toddler", UniformScorer(), seed=seed + 1, rate=1.0, temperature=2.0)
    assert other.injections != again.injections


def test_summary_counts(proposals):
    s = summary(proposals, LEVELS)
    assert s["types"]["pet"]["per_level"]["1"] == len(proposals[("A", "pet")].injections)


@pytest.mark.llm
def test_embedded_llm_proposals_are_plausible_and_cached(small, embedded_llm, tmp_path):
    from globe.reasoning.backends.embedded import EmbeddedBackend
    from globe.reasoning.cache import AnswerCache

    day = small.train[0]  # its morning: every step proposes, so each step is a batch of LLM questions
    morning = replace(day, minutes=day.minutes[:24], activities=day.activities[:24], locations=day.locations[:24])
    one_day = replace(small, train=(morning,), test=())
    backend = EmbeddedBackend(model_path=embedded_llm.model_path, cache=AnswerCache(tmp_path / "c.sqlite3"))
    first = propose(one_day, "toddler", LLMScorer(backend), seed=0, rate=1.0, temperature=2.0)
    assert first.injections and all(i.origin.startswith("llm:embedded") for i in first.injections)
    cached = EmbeddedBackend(model_path=embedded_llm.model_path, cache=AnswerCache(tmp_path / "c.sqlite3"))
    again = propose(one_day, "toddler", LLMScorer(cached), seed=0, rate=1.0, temperature=2.0)
    assert again.injections == first.injections
    assert cached.cache.hits > 0 and cached.cache.misses == 0
    # the scores see the activity: a toddler during breakfast carries food more than a razor
    from globe.noise.proposals import ProposalModel

    model = ProposalModel(LLMScorer(cached), small.objects, [" floor"])
    scores = model.object_scores("toddler", "breakfast")
    assert scores["food_cereal"] > scores["razor"]
