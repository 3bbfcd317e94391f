"""What a household created in the service runs, and the cross-validation that chooses it in the
background (:func:`globe.evaluation.deploy.choose_deployment` takes seconds: no request waits for it).

A household that needs no cross-validation (``method`` ``ngram`` or ``persistence``, or too few
training days) gets its deployment at once. Otherwise it runs the configured models while one
background thread at a time chooses; when it ends, the chosen deployment is handed to ``done``
(the registry stores it and rebuilds the household on its next request). A stop never waits for
a selection (daemon threads): one still to finish runs again on the household's next build.
"""

from __future__ import annotations

import logging
import threading
from typing import Any, Callable

from globe.config import CV_METHODS, Deployment, DeployMethod, GlobeConfig
from globe.data.records import Household
from globe.data.sensors import SensorData
from globe.recognition.recogniser import RecognitionSettings

log = logging.getLogger(__name__)
Done = Callable[[str, Deployment], None]


class Selections:
    """The households whose models are being chosen in the background."""

    def __init__(self, config: GlobeConfig, done: Done) -> None:
        self.config = config
        self.done = done
        self._running: set[str] = set()
        self._lock = threading.Lock()
        self._turn = threading.Lock()  # one selection at a time

    def needs_cv(self, household: Household, method: str) -> bool:
        """Whether ``method`` is chosen by cross-validation, and ``household`` has the days for it."""
        from globe.evaluation.deploy import too_few_days

        return CV_METHODS.get(method) is not None and too_few_days(household, self.config) is None

    def deployment(self, household: Household, method: DeployMethod) -> tuple[Deployment, bool]:
        """(what ``household`` runs now, whether that is final): the chosen deployment where no
        cross-validation is needed; else the configured one, and its selection is started."""
        from globe.evaluation.deploy import choose_deployment

        if not self.needs_cv(household, method):
            return choose_deployment(household, self.config, method=method), True
        name = household.name
        with self._lock:
            if name not in self._running:
                self._running.add(name)
                threading.Thread(target=self._run, args=(household, method), daemon=True,
                                 name=f"globe-select-{name}").start()
        return Deployment.configured(self.config, method, note="cross-validation on the training days is under way; "
                                                               "the configured models run until it ends"), False

    def running(self, name: str) -> bool:
        with self._lock:
            return name in self._running

    def _run(self, household: Household, method: Any) -> None:
        from globe.evaluation.deploy import choose_deployment

        name = household.name
        try:
            try:
                with self._turn:
                    deployment = choose_deployment(household, self.config, method=method)
            except Exception as err:  # noqa: BLE001 - the household keeps running its configured models
                log.exception("household %s: the selection of its models failed", name)
                why = f"cross-validation failed ({type(err).__name__}: {str(err)[:200]}); the configured models run"
                deployment = Deployment.configured(self.config, method, note=why)
            self.done(name, deployment)
        finally:
            with self._lock:
                self._running.discard(name)


def choose_recognition(household: Household, sensors: SensorData, step_minutes: int) -> RecognitionSettings:
    """The recogniser's settings of a household with sensors, as the evaluation deploys them
    (:func:`globe.evaluation.recognition.deployed_settings`)."""
    from globe.evaluation.recognition import deployed_settings

    return deployed_settings(household, sensors, step_minutes)
