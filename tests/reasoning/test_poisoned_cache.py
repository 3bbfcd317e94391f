"""A poisoned LLM answer cache: rows of the wrong JSON shape at the very keys the real backends
ask for are the n-gram fallback (counted as LLMCacheError), never an exception, and are deleted so
the question is asked afresh; a cache whose folder cannot be made does not stop anything."""

import math
import sqlite3

import pytest

from globe.assembly import object_chooser
from globe.config import GateConfig
from globe.errors import LLMCacheError, LLMError
from globe.reasoning.backends.embedded import EmbeddedBackend
from globe.reasoning.backends.remote import RemoteBackend
from globe.reasoning.cache import AnswerCache
from globe.reasoning.choice import run_context
from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import remote_prompt

POISON = ['"abc"', "[]", "{}", "NaN", "null", "1e999", '{"answer": "nope", "scores": {}}',
          '{"answer": 3, "scores": []}', "[" * 78 + "]" * 77]  # the last: not JSON at all


def an_uncertain_activity(model) -> str:
    return next(a for a in sorted(model.indexes_) if len([p for p in model.predict_proba(a).values() if p > 0.1]) >= 2)


def poison(path, key: str, value: str) -> None:
    db = sqlite3.connect(path)
    db.execute("INSERT OR REPLACE INTO answers (key, value) VALUES (?, ?)", (key, value))
    db.commit()
    db.close()


@pytest.mark.parametrize("value", POISON)
def test_a_poisoned_embedded_answer_is_the_ngram_fallback(tmp_path, fitted, value):
    path = tmp_path / "llm-answers.sqlite3"
    backend = EmbeddedBackend(n_threads=1, cache=AnswerCache(path))
    gate = object_chooser(fitted["A"].objects, GateConfig(threshold=1.0), backend, marginal=False)
    activity = an_uncertain_activity(fitted["A"].objects)
    ranked, dist = gate.ngram_ranking(activity, None, run_context(None, ()))
    candidates = gate.candidates_for(ranked, dist)
    key = backend._key(ChoiceContext(activity, run_context(None, ())(activity)), candidates)
    poison(path, key, value)
    choice = gate.choose_given(activity, None, run_context(None, ()))
    assert choice.asked and choice.fallback == LLMCacheError.__name__ and choice.obj == choice.ngram_choice
    assert backend.cache.errors["corrupt"] == 1
    assert sqlite3.connect(path).execute("SELECT COUNT(*) FROM answers").fetchone()[0] == 0  # asked afresh next time


@pytest.mark.parametrize("value", POISON[:6])
def test_a_poisoned_remote_answer_is_an_llm_error(tmp_path, value):
    path = tmp_path / "llm-answers.sqlite3"
    backend = RemoteBackend(base_url="http://127.0.0.1:1/v1", cache=AnswerCache(path), max_retries=0, timeout_s=1)
    context, candidates = ChoiceContext("cooking", ()), ("pan", "pot")
    from globe.reasoning.cache import cache_key

    key = cache_key(backend=backend.name, model=backend.model_name, base_url=backend.base_url,
                    prompt=remote_prompt(context, candidates), temperature=backend.temperature,
                    max_tokens=backend.max_tokens)
    poison(path, key, value)
    with pytest.raises(LLMError):  # the gate's fallback: off the list ("abc"), or a damaged cache entry
        backend.choose(context, candidates)


def test_a_cache_folder_that_is_a_file_fails_lookups_not_construction(tmp_path, fitted):
    blocker = tmp_path / "cache"
    blocker.write_text("not a folder")
    backend = EmbeddedBackend(n_threads=1, cache=AnswerCache(blocker / "llm-answers.sqlite3"))
    gate = object_chooser(fitted["A"].objects, GateConfig(threshold=1.0), backend, marginal=False)
    choice = gate.choose_given(an_uncertain_activity(fitted["A"].objects), None, run_context(None, ()))
    assert choice.fallback == LLMCacheError.__name__ and backend.cache.errors["missing"] >= 1
    assert math.isfinite(choice.confidence)
