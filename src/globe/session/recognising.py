"""The sensor side of a household session: recognising the activity, asking about it, learning it.

:class:`SensorSteps` is the part of :class:`~globe.session.session.HouseholdSession` that reads a
household's ambient sensors (:mod:`globe.session.sensing`): checking the events observations
carry, consulting the question policy after each observation, reading the recognised activity
(now and for every step today) and counting each finished day into the sensor emission. It
shares the session's state and lock; the session's one activity filter does the inference.

A household created with sensors and no labelled day (a cold start) has no activity model to be
unsure with yet, and knows no activity's name but those the person says: its budget of questions
is spread evenly over the day from its first step (every step as uncertain as any other),
each question offering the activities heard so far as equally likely, or none (an open "what are
you doing?") before the first answer. The answers label their steps, which the sensor emission
counts at the day's end and from which the first day is learned (the session fills the steps
between from the nearest answer), so the next day recognises and asks as any household does.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from globe.data.records import Household
from globe.data.sensors import SensorDay
from globe.errors import DataError, UnknownLabelError
from globe.inference.activity_filter import ActivityFilter, Belief, smoothed
from globe.recognition.asking import DayAsker, worth
from globe.recognition.recogniser import spread_answers
from globe.session.grid import DayGrid
from globe.session.records import instant
from globe.session.sensing import MAX_OPTIONS, Question, SensorEvent, SessionSensors


class SensorSteps:
    """The sensor methods of a household session (see module doc)."""

    household: Household
    sensing: SessionSensors | None
    grid: DayGrid
    _filter: ActivityFilter | None
    _beliefs: list[Belief]
    _edges_last: np.ndarray | None  # the last observed step's evidence on the change after it (1 x labels x labels)
    _labels: list[str | None]
    _looked: list[bool]
    _uses: list[frozenset[str]]
    _day: str | None
    _events: list[tuple[int, float, float]]
    _sensor_day: SensorDay | None
    _asker: DayAsker | None
    _question: Question | None
    _asked: list[int]
    _worths: dict[int, float]
    _recognition: tuple[tuple, list[tuple[str, float] | None]] | None

    def _filtered(self) -> Belief | None:  # pragma: no cover - the session's
        raise NotImplementedError

    def _state(self) -> tuple:  # pragma: no cover - the session's
        raise NotImplementedError

    def known_activities(self) -> tuple[str, ...]:  # pragma: no cover - the session's
        raise NotImplementedError

    def validate_sensors(self, events: Sequence[SensorEvent]) -> None:
        """Sensor events name the household's sensors and end no earlier than they start."""
        if self.sensing is None:
            raise DataError(f"household {self.household.name} has no sensors (create it with its sensors to send "
                            "sensor events)", field="sensors")
        for i, event in enumerate(events):
            if event.sensor not in self.sensing.index:
                known = ", ".join(s.name for s in self.sensing.sensors[:20])
                raise UnknownLabelError(f"unknown sensor {event.sensor[:64]!r} (the household's sensors: {known})",
                                        field=f"sensors[{i}].sensor")
            if instant(event.end) < instant(event.start):
                raise DataError(f"sensor event ends ({event.end.isoformat()}) before it starts "
                                f"({event.start.isoformat()})", field=f"sensors[{i}].end")

    def _consult(self, step: int) -> None:
        """Ask the question policy about ``step`` when it has no label (after each observation, so a
        replay of the same observations asks the same questions)."""
        if self._labels[step] is not None:
            return
        if self._filter is None:
            self._consult_cold(step)
            return
        if self._asker is None:
            return
        belief = self._filtered()
        if belief is None or belief.step != step:
            return
        post = self._filter.posterior(belief)[0]
        self._worths[step] = float(worth(post, self._asker.labelled))
        if self._asker(step, post):
            self._asked.append(step)
            names = list(self._filter.labels)
            order = np.argsort(-post, kind="stable")[:MAX_OPTIONS]
            options = tuple((names[int(i)], float(post[i])) for i in order if post[i] > 0)
            self._question = Question(self._day or "", step, options)

    def _consult_cold(self, step: int) -> None:
        """Before a first day is learned (see module doc): the k-th of the budget's questions is
        asked at the first observed step from ``k * steps / budget`` on, offering the activities
        the household knows so far, equally likely (none: an open question)."""
        sensing = self.sensing
        if sensing is None or self._day is None or len(self._asked) >= sensing.budget:
            return
        if step < len(self._asked) * self.grid.steps // sensing.budget:
            return
        self._asked.append(step)
        known = self.known_activities()
        self._question = Question(self._day, step, tuple((a, 1.0 / len(known)) for a in known[:MAX_OPTIONS]))

    def _today_events(self) -> SensorDay:
        """Today's sensor activations so far (seconds after today's midnight)."""
        if self._sensor_day is None:
            self._sensor_day = SensorDay.of(self._day or "", self._events)
        return self._sensor_day

    def recognised(self) -> tuple[str, float] | None:
        """The activity under way at the last observed step and its probability, recognised from
        the sensors (and movements) where the step has no label; None otherwise."""
        if self.sensing is None or not self._labels or self._labels[-1] is not None:
            return None
        belief = self._filtered()
        if self._filter is None or belief is None or belief.step < 0:
            return None
        post = self._filter.posterior(belief)[0]
        best = int(np.argmax(post))
        return self._filter.labels[best], float(post[best])

    def question(self) -> Question | None:
        """The question asked at the last observed step, while it has no answer (None: none)."""
        q = self._question
        if q is None or q.day != self._day or q.step != len(self._labels) - 1 or self._labels[q.step] is not None:
            return None
        return q

    def questions_today(self) -> tuple[int, int]:
        """(questions asked today, those answered): what the dashboard counts."""
        return len(self._asked), sum(self._labels[t] is not None for t in self._asked if t < len(self._labels))

    def recognised_today(self) -> list[tuple[str, float] | None]:
        """Per step today, the activity the sensors read there and its probability, online and with
        the step's own label left out (the steps before it as observed), so a labelled step shows
        what recognition would have said beside its label; None without sensors or a learned day."""
        n = len(self._labels)
        belief = self._filtered() if self.sensing is not None else None
        flt, sensing = self._filter, self.sensing
        if belief is None or flt is None or sensing is None:
            return [None] * n
        key = self._state()
        if self._recognition is not None and self._recognition[0] == key:
            return list(self._recognition[1])
        after = {b.step: b for b in self._beliefs}
        features = sensing.features(self._today_events(), [self.grid.minute(t) for t in range(n)])
        labels = list(flt.labels)
        likes, edges = sensing.likelihoods(features, labels), sensing.edge_tables(features, labels)
        out: list[tuple[str, float] | None] = []
        for t in range(n):
            found, before = after.get(t), after.get(t - 1)
            if found is not None and self._labels[t] is not None and before is not None:
                moved = self._uses[t] if t and self._looked[t] and self._looked[t - 1] else None
                found = flt.update(before, t, [None], [moved], likelihood=likes[t][None, :],
                                   edges=edges[t - 1][None] if edges is not None and t else None)
            if found is None:
                out.append(None)
                continue
            post = flt.posterior(found)[0]
            best = int(np.argmax(post))
            out.append((labels[best], float(post[best])))
        self._recognition = (key, out)
        return list(out)

    def step_counts(self) -> tuple[int, int]:
        """(today's labelled steps, today's steps recognised from the sensors) up to the last observed."""
        labelled = len(self._labels) - self._labels.count(None)
        return labelled, (len(self._labels) - labelled if self.sensing is not None and self._filter is not None else 0)

    def _learn_sensors(self) -> None:
        """The sensor emission counts the finished day's labelled steps, each label spread over the
        stretch read (with hindsight) as one activity; its worths of asking join the reference."""
        sensing = self.sensing
        if sensing is None or not self._labels:
            return
        if self._worths:
            sensing.add_reference([self._worths[t] for t in sorted(self._worths)])
        if all(a is None for a in self._labels):
            return
        labels: list[str | None] = list(self._labels)
        belief = self._filtered() if None in labels else None
        if belief is not None and self._filter is not None and belief.step == len(labels) - 1:
            labels = spread_answers(smoothed(self._filter, belief)[0].argmax(axis=1).tolist(), labels)
        minutes = [self.grid.minute(t) for t in range(len(labels))]
        sensing.learn([sensing.features(self._today_events(), minutes)], [labels])
