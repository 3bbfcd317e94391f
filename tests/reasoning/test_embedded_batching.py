"""The embedded backend's shared-prefix scoring equals scoring each candidate on its own."""

import pytest

from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import NULL_PREFIX, cloze_continuation, cloze_prefix, diary_prefix

pytestmark = pytest.mark.llm

OBJECTS = ("milk", "food_cereal", "food_jam", "food_peanut_butter", "tooth_paste", "toothbrush", "deck_of_cards",
           "coffee_filter", "coffee_cup", "bowl")
CONTINUATIONS = [cloze_continuation(o) for o in OBJECTS]
BREAKFAST = ChoiceContext("breakfast", ("bowl",), (("bowl", "food_cereal", "milk"), ("bowl", "food_jam"), ("bowl", "milk")))
PROMPTS = [cloze_prefix(ChoiceContext("breakfast", ("bowl", "spoon"))), NULL_PREFIX, diary_prefix(BREAKFAST)]


def _token_counts(backend) -> list[int]:
    llm = backend._shared().llm
    return [len(llm.tokenize(c.encode("utf-8"), add_bos=False)) for c in CONTINUATIONS]


@pytest.mark.parametrize("prompt", PROMPTS, ids=["cloze", "null", "diary"])
def test_trie_scores_equal_the_one_by_one_reference(embedded_llm, prompt):
    from globe.reasoning.backends.embedded import _sequential_logprobs

    counts = _token_counts(embedded_llm)
    assert {1, 2} <= set(counts) and max(counts) >= 3  # the candidates cover 1, 2 and 3+ tokens
    assert "\n" in PROMPTS[2]  # the diary is a multi-line prompt (head reused from the cache)
    reference = _sequential_logprobs(embedded_llm, prompt, CONTINUATIONS)
    scores = embedded_llm.continuation_logprobs(prompt, CONTINUATIONS)
    assert len(scores) == len(CONTINUATIONS)
    assert scores == reference  # the same single-token decodes and float64 sums: the same bits
    assert max(range(len(scores)), key=scores.__getitem__) == max(range(len(reference)), key=reference.__getitem__)


def test_scores_do_not_depend_on_order_subset_or_history(embedded_llm):
    prompt = PROMPTS[2]
    full = dict(zip(CONTINUATIONS, embedded_llm.continuation_logprobs(prompt, CONTINUATIONS)))
    embedded_llm.continuation_logprobs(PROMPTS[0], CONTINUATIONS[::2])  # something else in between
    backwards = embedded_llm.continuation_logprobs(prompt, CONTINUATIONS[::-1])
    assert dict(zip(CONTINUATIONS[::-1], backwards)) == full
    subset = CONTINUATIONS[1:4] + [CONTINUATIONS[1]]  # shares "food" starts; a repeated name
    assert embedded_llm.continuation_logprobs(prompt, subset) == [full[c] for c in subset]


def test_shared_starts_are_decoded_once(embedded_llm, monkeypatch):
    """One decode per distinct proper token prefix, fewer than one per token after the first."""
    llm = embedded_llm._shared().llm
    tails = [llm.tokenize(c.encode("utf-8"), add_bos=False) for c in CONTINUATIONS]
    prefixes = {tuple(t[:d]) for t in tails for d in range(1, len(t))}
    one_by_one = sum(len(t) - 1 for t in tails)
    assert len(prefixes) < one_by_one  # the chosen names do share starts ("food", "coffee")
    embedded_llm.continuation_logprobs(NULL_PREFIX, CONTINUATIONS)  # the prompt's own decode is not counted below
    calls = []
    real_eval = llm.eval
    monkeypatch.setattr(llm, "eval", lambda tokens: (calls.append(list(tokens)), real_eval(tokens))[1])
    embedded_llm.continuation_logprobs(NULL_PREFIX, CONTINUATIONS)
    prompt_calls = 1  # a one-line prompt is evaluated afresh in one batch
    assert len(calls) == prompt_calls + len(prefixes)
    assert all(len(c) == 1 for c in calls[prompt_calls:])
