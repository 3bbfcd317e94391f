"""A household session's decision as the service's answer (the ``Prediction`` a robot reads)."""

from __future__ import annotations

from globe.service.schemas import FetchOut, Prediction, QuestionOut, RecognisedOut
from globe.session import Decision


def prediction(d: Decision, shadow: bool, clock: str | None = None) -> Prediction:
    """The service's answer for a decision: ``act`` only outside shadow mode (``clock``: the
    question's step as HH:MM)."""
    choice = d.choice
    first = d.fetches[0] if d.fetches else None
    return Prediction(status=d.status, days_learned=d.days_learned, day=d.day, step=d.step, activity=d.activity,
                      activity_probability=d.activity_probability, object=choice.obj if choice else None,
                      object_probability=choice.confidence if choice else 0.0,
                      llm_consulted=bool(choice and choice.asked), llm_fallback=choice.fallback if choice else None,
                      act=first is not None and not shadow, fetch_object=first.obj if first else None,
                      fetch_to=first.to_location if first else None,
                      fetch_probability=first.probability if first else None,
                      fetches=[FetchOut(object=c.obj, to=c.to_location, probability=c.probability) for c in d.fetches],
                      shadow=shadow,
                      recognised=RecognisedOut(activity=d.recognised[0], probability=d.recognised[1])
                      if d.recognised else None,
                      labelled_steps=d.labelled_steps, recognised_steps=d.recognised_steps,
                      question=None if d.question is None else QuestionOut(
                          day=d.question.day, step=d.question.step, time=clock or "",
                          activities=[RecognisedOut(activity=a, probability=p) for a, p in d.question.options]))
