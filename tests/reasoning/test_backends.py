"""The real backends: Gemma 3 270M in process, and the remote client against a real server."""

import subprocess
import sys

import pytest

from globe.errors import LLMAnswerError, LLMUnavailableError
from globe.models.objects import ObjectModel
from globe.reasoning.backends.remote import RemoteBackend, match_candidate
from globe.reasoning.cache import AnswerCache
from globe.reasoning.context import ChoiceContext
from globe.reasoning.gate import UncertaintyGate

pytestmark = pytest.mark.llm

UNAMBIGUOUS = [
    (ChoiceContext("brushing_teeth", ("toothbrush",)), ("book", "fryingpan", "tooth_paste"), "tooth_paste"),
    (ChoiceContext("breakfast", ("bowl", "food_cereal")), ("milk", "toothbrush", "vacuum_cleaner"), "milk"),
    (ChoiceContext("reading", ()), ("book", "knife", "trashbag"), "book"),
    (ChoiceContext("making_coffee", ("coffee_filter",)), ("ground_coffee", "hairdryer", "razor"), "ground_coffee"),
]


@pytest.mark.parametrize("context, candidates, obvious", UNAMBIGUOUS)
def test_embedded_picks_the_obvious_object(embedded_llm, context, candidates, obvious):
    choice = embedded_llm.choose(context, candidates)
    assert choice.answer in candidates
    assert choice.answer == obvious
    assert set(choice.scores) == set(candidates)


def test_embedded_choice_does_not_depend_on_candidate_order(embedded_llm):
    context, candidates, _ = UNAMBIGUOUS[0]
    assert embedded_llm.choose(context, candidates).answer == embedded_llm.choose(context, candidates[::-1]).answer


def test_embedded_answers_are_cached_on_disk(gguf_path, tmp_path):
    from globe.reasoning.backends.embedded import EmbeddedBackend

    cache = AnswerCache(tmp_path / "answers.sqlite3")
    first = EmbeddedBackend(model_path=gguf_path, cache=cache).choose(*UNAMBIGUOUS[2][:2])
    again = EmbeddedBackend(model_path=gguf_path, cache=AnswerCache(tmp_path / "answers.sqlite3"))
    second = again.choose(*UNAMBIGUOUS[2][:2])
    assert second.cached and not first.cached and second.answer == first.answer


def test_cache_survives_a_killed_process(tmp_path):
    path = tmp_path / "c.sqlite3"
    code = ("from globe.reasoning.cache import AnswerCache; import os; c = AnswerCache(%r); "
            "c.put('k1', {'answer': 'milk'}); os._exit(9)") % str(path)
    assert subprocess.run([sys.executable, "-c", code]).returncode == 9
    assert AnswerCache(path).get("k1") == {"answer": "milk"}


def test_remote_backend_round_trip_against_a_real_server(llm_server):
    """Greedy decoding makes the server's reply reproducible: ask it directly with the paper's
    prompt, then check that the backend turns the same reply into exactly the expected outcome."""
    import openai

    from globe.reasoning.backends.remote import SYSTEM
    from globe.reasoning.prompts import remote_prompt

    backend = RemoteBackend(model="gemma", base_url=llm_server, api_key="unused", temperature=0.0, timeout_s=60,
                            max_retries=0)
    context, candidates, _ = UNAMBIGUOUS[0]
    direct = openai.OpenAI(base_url=llm_server, api_key="unused").chat.completions.create(
        model="gemma", temperature=0.0, max_tokens=backend.max_tokens,
        messages=[{"role": "system", "content": SYSTEM},
                  {"role": "user", "content": remote_prompt(context, candidates)}])
    reply = direct.choices[0].message.content or ""
    expected = match_candidate(reply, candidates) if reply.strip() else None
    if expected is None:  # a base model often answers off the list: reported, with the reply
        with pytest.raises(LLMAnswerError) as err:
            backend.choose(context, candidates)
        assert err.value.raw == reply
    else:
        choice = backend.choose(context, candidates)
        assert choice.answer == expected and choice.raw == reply


def test_gate_over_the_real_server_never_loses_the_prediction(llm_server):
    model = ObjectModel().fit([("eat", ("bowl", "milk")), ("eat", ("bowl", "cereal")), ("eat", ("bowl", "spoon"))])
    backend = RemoteBackend(model="gemma", base_url=llm_server, api_key="unused", timeout_s=60, max_retries=0)
    gate = UncertaintyGate(model, backend)
    choice = gate.choose("eat", ("bowl",))  # three-way tie at 1/3: the gate opens
    assert choice.asked and choice.candidates == ("cereal", "milk", "spoon")
    assert choice.obj in choice.candidates
    assert choice.fallback in (None, "LLMAnswerError")  # an off-list reply is an answer error
    if choice.fallback:
        assert choice.obj == choice.ngram_choice == "cereal"  # tie broken by name: the n-gram's pick
    assert choice.answer  # the raw or validated reply was recorded


def test_remote_backend_unreachable_server_is_an_llm_error():
    from tests.helpers import free_port

    backend = RemoteBackend(model="m", base_url=f"http://127.0.0.1:{free_port()}/v1", api_key="x", timeout_s=2,
                            max_retries=0)
    with pytest.raises(LLMUnavailableError):
        backend.choose(ChoiceContext("eat", ()), ("milk", "bowl"))


def test_reply_matching():
    assert match_candidate("Tooth Paste", ("tooth_paste", "book")) == "tooth_paste"
    assert match_candidate("book\nbecause reading", ("tooth_paste", "book")) == "book"
    assert match_candidate("a spoon maybe", ("spoon",)) is None


def test_personalised_prompt_follows_this_persons_habit(embedded_llm):
    # a person who listens to a headset while reading: the habit beats the generic "book"
    habit = (("headset",), ("headset",), ("headset",))
    context = ChoiceContext("reading", (), habit)
    choice = embedded_llm.choose(context, ("book", "headset"))
    assert choice.answer == "headset"
    other = ChoiceContext("reading", (), (("book",), ("book",), ("book",)))
    assert embedded_llm.choose(other, ("book", "headset")).answer == "book"


def test_scores_do_not_depend_on_what_was_evaluated_before(embedded_llm):
    # nothing asked in between may change a score: the same question before and after others
    context = ChoiceContext("breakfast", ("bowl",), (("bowl", "milk"), ("bowl", "milk")))
    first = embedded_llm.score(context, ("milk", "spoon", "toothbrush"))
    embedded_llm.score(ChoiceContext("breakfast", ("plate",), (("plate", "fork"),)), ("fork", "milk"))
    embedded_llm.score(ChoiceContext("reading", ()), ("book", "knife"))
    embedded_llm.score(context, ("milk", "spoon"))  # same diary
    embedded_llm._memo.clear()  # computed again, not remembered
    assert embedded_llm.score(context, ("milk", "spoon", "toothbrush")) == first
