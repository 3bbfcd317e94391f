"""The gate's logic with scripted backends (test doubles: the real backends are tested beside)."""


import pytest

from globe.config import GateConfig
from globe.errors import LLMAnswerError, LLMTimeoutError
from globe.models.objects import ObjectModel
from globe.reasoning.backends.base import Choice, LLMBackend
from globe.reasoning.context import normalise_answer
from globe.reasoning.gate import LLMOnlyChooser, UncertaintyGate

# During "eat", after "bowl": milk 3, cereal 2, spoon 1 (p = .5, .33, .17); first object: bowl
RUNS = [("eat", ("bowl", "milk")), ("eat", ("bowl", "milk")), ("eat", ("bowl", "milk")),
        ("eat", ("bowl", "cereal")), ("eat", ("bowl", "cereal")), ("eat", ("bowl", "spoon")),
        ("eat", ("plate", "fork")), ("eat", ("plate", "knife")), ("eat", ("plate", "knife"))]
DEFAULTS = GateConfig()


class Scripted(LLMBackend):
    name = "scripted"

    def __init__(self, answer=None, error=None, scores=None):
        self.answer, self.error, self.scores, self.calls = answer, error, scores, []

    def choose(self, context, candidates):
        self.calls.append((context, candidates))
        if self.error:
            raise self.error
        return Choice(self.answer if self.answer is not None else candidates[-1], self.scores)


@pytest.fixture(scope="module")
def model():
    return ObjectModel().fit(RUNS)


def gate(model, backend, **kw):
    params = dict(threshold=DEFAULTS.threshold, top_k=DEFAULTS.top_k, min_prob=DEFAULTS.min_prob) | kw
    return UncertaintyGate(model, backend, **params)


def test_defaults_are_the_papers():
    assert (DEFAULTS.threshold, DEFAULTS.top_k, DEFAULTS.min_prob) == (0.5, 5, 0.1)


def test_confident_prediction_does_not_ask(model):
    backend = Scripted()
    choice = gate(model, backend).choose("eat", ("bowl",))  # p(milk) = 0.5 is not below d = 0.5
    assert choice.obj == "milk" and not choice.asked and backend.calls == []


def test_uncertain_prediction_asks_with_filtered_candidates(model):
    backend = Scripted(answer="knife")
    # first object: bowl 6/9 -> confident; after "plate": knife 2/3 confident; P(o|eat) unigram
    # after an unseen object: bowl .33, milk .17, plate .17, cereal .11, knife .11, spoon .06, fork .06
    choice = gate(model, backend).choose("eat", ("teapot",))
    assert choice.asked and choice.fallback is None
    assert backend.calls[0][1] == ("bowl", "milk", "plate", "cereal", "knife")  # top-5, all p > 0.1
    assert choice.obj == "knife" and choice.ngram_choice == "bowl"


def test_min_prob_and_top_k_filter(model):
    backend = Scripted()
    gate(model, backend, top_k=3, min_prob=0.15).choose("eat", ("teapot",))
    assert backend.calls[0][1] == ("bowl", "milk", "plate")


def test_fewer_than_two_candidates_does_not_ask(model):
    backend = Scripted()
    choice = gate(model, backend, threshold=0.9, min_prob=0.5).choose("eat", ("bowl",))
    assert not choice.asked and choice.obj == "milk" and backend.calls == []


@pytest.mark.parametrize("backend, reason", [
    (Scripted(answer="toaster"), "off_list"),
    (Scripted(error=LLMAnswerError("empty answer", raw="")), "LLMAnswerError"),
    (Scripted(error=LLMTimeoutError("no answer within 1 s")), "LLMTimeoutError"),
])
def test_failures_fall_back_to_the_ngram_choice_and_are_counted(model, backend, reason):
    g = gate(model, backend)
    choice = g.choose("eat", ("teapot",))
    assert choice.obj == "bowl" and choice.asked and choice.fallback == reason and choice.ngram_choice == "bowl"


def test_combine_mode_adds_ngram_log_probability(model):
    # LLM prefers cereal by 0.5 nats; n-gram says milk is 1.5x as likely (log 1.5 = 0.405)
    scores = {"milk": 0.0, "cereal": 0.5, "spoon": -5.0}
    g = gate(model, Scripted(answer="cereal", scores=scores), threshold=0.9, mode="combine", combine_weight=1.0)
    assert g.choose("eat", ("bowl",)).obj == "cereal"  # 0.5 + log(1/3) > 0 + log(1/2)
    g2 = gate(model, Scripted(answer="cereal", scores=scores), threshold=0.9, mode="combine", combine_weight=2.0)
    assert g2.choose("eat", ("bowl",)).obj == "milk"  # 0.5 + 2 log(1/3) < 2 log(1/2)


def test_llm_only_offers_every_object_of_the_activity(model):
    backend = Scripted(answer="fork")
    choice = LLMOnlyChooser(model, backend).choose("eat", ())
    assert backend.calls[0][1] == ("bowl", "cereal", "fork", "knife", "milk", "plate", "spoon")
    assert choice.obj == "fork"


@pytest.mark.parametrize("reply, expected", [
    ("Tooth_Paste", "tooth_paste"), ("  tooth paste.", "tooth_paste"), ("`milk`", "milk"),
    ("food-peanut butter", "food_peanut_butter")])
def test_answers_are_normalised(reply, expected):
    assert normalise_answer(reply) == expected


def test_personalised_gate_sends_the_persons_recent_runs(model):
    backend = Scripted(answer="bowl")
    gate(model, backend, examples=2).choose("eat", ("teapot",))
    context = backend.calls[0][0]
    assert context.examples == (("plate", "knife"), ("plate", "knife"))  # the last two runs of "eat"
    assert model.recent_runs("eat", 3) == (("plate", "fork"), ("plate", "knife"), ("plate", "knife"))


def test_prompts_show_the_habits():
    from globe.reasoning.context import ChoiceContext
    from globe.reasoning.prompts import diary_prefix, remote_prompt

    ctx = ChoiceContext("breakfast", ("bowl",), (("bowl", "food_cereal"), ("plate",)))
    assert diary_prefix(ctx) == ("Day 1, breakfast: bowl, food cereal.\nDay 2, breakfast: plate.\n"
                                 "Day 3, breakfast: bowl,")
    text = remote_prompt(ctx, ("milk", "spoon"))
    assert "- bowl -> food_cereal" in text
    assert text.endswith("Return only one object name from this list: [milk, spoon]")
