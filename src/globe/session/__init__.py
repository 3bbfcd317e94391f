"""The online loop of a household (:class:`HouseholdSession`), which the service, the command
line and the evaluation all drive, and what it is built from (:func:`build_session`)."""

from globe.session.build import build_session, deployment_summary, session_grid
from globe.session.grid import DayGrid
from globe.session.records import Decision, Observation, Placement
from globe.session.session import HouseholdSession

__all__ = ["DayGrid", "Decision", "HouseholdSession", "Observation", "Placement", "build_session",
           "deployment_summary", "session_grid"]
