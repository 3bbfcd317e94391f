"""The embedded backend's batched scoring equals scoring each token node on its own."""

import pytest

from globe.reasoning.cache import AnswerCache
from globe.reasoning.context import ChoiceContext
from globe.reasoning.prompts import NULL_PREFIX, cloze_continuation, cloze_prefix, diary_prefix

pytestmark = pytest.mark.llm

OBJECTS = ("milk", "food_cereal", "food_jam", "food_peanut_butter", "tooth_paste", "toothbrush", "deck_of_cards",
           "coffee_filter", "coffee_cup", "bowl")
CONTINUATIONS = [cloze_continuation(o) for o in OBJECTS]
BREAKFAST = ChoiceContext("breakfast", ("bowl",),
                          (("bowl", "food_cereal", "milk"), ("bowl", "food_jam"), ("bowl", "milk")))
PROMPTS = [cloze_prefix(ChoiceContext("breakfast", ("bowl", "spoon"))), NULL_PREFIX, diary_prefix(BREAKFAST)]
LONG_DIARY = diary_prefix(ChoiceContext("breakfast", ("bowl",), tuple(
    ("bowl", "food_cereal", "milk", "coffee_cup", "coffee_filter", OBJECTS[i % len(OBJECTS)]) for i in range(12))))


def _token_counts(backend) -> list[int]:
    rt = backend._shared()
    return [len(rt.tokenize(c, False)) for c in CONTINUATIONS]


@pytest.mark.parametrize("prompt", PROMPTS + [LONG_DIARY], ids=["cloze", "null", "diary", "long-diary"])
def test_batched_scores_equal_the_one_node_at_a_time_reference(embedded_llm, prompt):
    from globe.reasoning.backends.embedded import reference_logprobs

    if prompt is LONG_DIARY:  # past 256 tokens llama.cpp pads the cache to 512 cells: other kernels
        assert 256 < len(embedded_llm._shared().tokenize(prompt, True)) < embedded_llm.n_ctx - 32

    counts = _token_counts(embedded_llm)
    assert {1, 2} <= set(counts) and max(counts) >= 3  # the candidates cover 1, 2 and 3+ tokens
    assert "\n" in PROMPTS[2]  # the diary is a multi-line prompt
    reference = reference_logprobs(embedded_llm, prompt, CONTINUATIONS)
    scores = embedded_llm.continuation_logprobs(prompt, CONTINUATIONS)
    assert len(scores) == len(CONTINUATIONS)
    assert scores == reference  # the same arithmetic per row and float64 sums: the same bits


def test_scores_do_not_depend_on_order_subset_or_the_other_questions(embedded_llm):
    prompt = PROMPTS[2]
    full = dict(zip(CONTINUATIONS, embedded_llm.continuation_logprobs(prompt, CONTINUATIONS)))
    backwards = embedded_llm.continuation_logprobs(prompt, CONTINUATIONS[::-1])
    assert dict(zip(CONTINUATIONS[::-1], backwards)) == full
    subset = CONTINUATIONS[1:4] + [CONTINUATIONS[1]]  # shares "food" starts; a repeated name
    assert embedded_llm.continuation_logprobs(prompt, subset) == [full[c] for c in subset]
    # asked together with other prompts (one forest, shared starts) and without the memo
    together = embedded_llm.continuation_logprobs_many([(PROMPTS[0], CONTINUATIONS[::2]), (prompt, subset),
                                                        (PROMPTS[1], CONTINUATIONS)])
    assert together[1] == [full[c] for c in subset]
    assert together[0] == embedded_llm.continuation_logprobs(PROMPTS[0], CONTINUATIONS)[::2]


def test_prefetch_stores_the_answers_one_by_one_questions_get(gguf_path, embedded_llm, tmp_path):
    from globe.reasoning.backends.embedded import EmbeddedBackend

    questions = [(ChoiceContext("breakfast", ("bowl",)), ("milk", "food_cereal", "spoon")),
                 (ChoiceContext("breakfast", ("bowl", "milk")), ("food_cereal", "spoon")),
                 (BREAKFAST, ("milk", "food_jam", "coffee_cup")),
                 (ChoiceContext("brushing_teeth", ()), ("toothbrush", "tooth_paste"))]
    batched = EmbeddedBackend(model_path=gguf_path, cache=AnswerCache(tmp_path / "a.sqlite3"))
    batched.prefetch(questions + questions[:1])
    rows_after_prefetch = batched._shared().rows
    answers = [batched.choose(c, cands) for c, cands in questions]
    assert all(a.cached for a in answers)  # every question was answered ahead, nothing decoded since
    assert batched._shared().rows == rows_after_prefetch
    one_by_one = EmbeddedBackend(model_path=gguf_path, cache=AnswerCache(tmp_path / "b.sqlite3"))
    for (context, cands), answer in zip(questions, answers):
        alone = one_by_one.choose(context, cands)
        assert not alone.cached and (alone.answer, alone.scores) == (answer.answer, answer.scores)


def test_shared_starts_are_decoded_once(embedded_llm):
    """One row per distinct token prefix: the prompt's tokens and each candidate's proper
    prefixes, shared by every candidate that starts with them."""
    rt = embedded_llm._shared()
    prompt = rt.tokenize(NULL_PREFIX, True)
    tails = [rt.tokenize(c, False) for c in CONTINUATIONS]
    prefixes = {tuple(t[:d]) for t in tails for d in range(1, len(t))}
    assert len(prefixes) < sum(len(t) - 1 for t in tails)  # the chosen names do share starts ("food", "coffee")
    before = rt.rows
    embedded_llm.continuation_logprobs(NULL_PREFIX, CONTINUATIONS)
    assert rt.rows - before == len(prompt) + len(prefixes)


def test_a_question_too_long_for_the_context_does_not_stop_the_others_being_batched(gguf_path, embedded_llm, tmp_path):
    from globe.errors import LLMError
    from globe.reasoning.backends.embedded import EmbeddedBackend

    runs = tuple(("bowl", "food_cereal", "milk", "coffee_cup", "coffee_filter", "toothbrush") for _ in range(40))
    too_long = (ChoiceContext("breakfast", ("bowl",), runs), ("milk", "food_jam"))
    questions = [(ChoiceContext("breakfast", ("bowl",)), ("milk", "food_cereal", "spoon")),
                 (BREAKFAST, ("milk", "food_jam", "coffee_cup")),
                 (ChoiceContext("brushing_teeth", ()), ("toothbrush", "tooth_paste"))]
    backend = EmbeddedBackend(model_path=gguf_path, cache=AnswerCache(tmp_path / "a.sqlite3"))
    rt = backend._shared()
    decodes = rt.decodes
    backend.prefetch(questions + [too_long])  # the long one is left out of the batch, not the others
    assert rt.decodes - decodes <= 3
    assert all(backend.choose(c, cands).cached for c, cands in questions)
    with pytest.raises(LLMError, match="n_ctx"):
        backend.choose(*too_long)
