"""What the service's SQLite database holds: its tables, created and migrated in order
(``PRAGMA user_version`` counts the migrations applied; ``application_id`` marks the file as
GLOBE's), and the rows :class:`globe.service.store.Store` reads back from them."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

APPLICATION_ID = 0x474C4F42  # "GLOB"

MIGRATIONS: list[str] = [
    # 1: the first schema
    """
    CREATE TABLE households (
        name TEXT PRIMARY KEY,
        nodes TEXT NOT NULL,
        objects TEXT NOT NULL,
        created_at TEXT NOT NULL
    );
    CREATE TABLE training_days (
        household TEXT NOT NULL REFERENCES households(name),
        position INTEGER NOT NULL,
        day TEXT NOT NULL,
        PRIMARY KEY (household, position)
    );
    CREATE TABLE observations (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        time TEXT NOT NULL,
        activity TEXT NOT NULL,
        locations TEXT NOT NULL,
        received_at TEXT NOT NULL
    );
    CREATE INDEX observations_by_household ON observations(household, id);
    """,
    # 2: what the person said about fetched objects
    """
    CREATE TABLE feedback (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        object TEXT NOT NULL,
        accepted INTEGER NOT NULL,
        received_at TEXT NOT NULL
    );
    """,
    # 3: time zones, unknown activities, client ids (idempotent retries), quarantine, tokens
    f"""
    ALTER TABLE households ADD COLUMN timezone TEXT NOT NULL DEFAULT 'UTC';
    CREATE TABLE observations_v3 (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        time TEXT NOT NULL,
        activity TEXT,
        locations TEXT NOT NULL,
        received_at TEXT NOT NULL,
        client_id TEXT,
        ack TEXT,
        quarantined INTEGER NOT NULL DEFAULT 0
    );
    INSERT INTO observations_v3 (id, household, time, activity, locations, received_at)
        SELECT id, household, time, activity, locations, received_at FROM observations;
    DROP TABLE observations;
    ALTER TABLE observations_v3 RENAME TO observations;
    CREATE INDEX observations_by_household ON observations(household, id);
    CREATE UNIQUE INDEX observations_by_client_id ON observations(household, client_id) WHERE client_id IS NOT NULL;
    CREATE TABLE tokens (
        id TEXT PRIMARY KEY,
        hash TEXT NOT NULL UNIQUE,
        household TEXT,
        admin INTEGER NOT NULL,
        created_at TEXT NOT NULL,
        revoked_at TEXT
    );
    PRAGMA application_id = {APPLICATION_ID};
    """,
    # 4: shadow mode, online scores (one-step predictions, fetch decisions, per-day scores), the
    # dashboard's session secret. Households stored before keep acting (shadow 0); new ones start in shadow.
    """
    ALTER TABLE households ADD COLUMN shadow INTEGER NOT NULL DEFAULT 0;
    CREATE TABLE step_predictions (
        household TEXT NOT NULL REFERENCES households(name),
        day TEXT NOT NULL,
        step INTEGER NOT NULL,
        activity TEXT NOT NULL,
        probability REAL NOT NULL,
        observed TEXT,
        PRIMARY KEY (household, day, step)
    );
    CREATE TABLE fetches (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        household TEXT NOT NULL REFERENCES households(name),
        day TEXT NOT NULL,
        step INTEGER NOT NULL,
        object TEXT NOT NULL,
        to_location TEXT,
        probability REAL,
        shadow INTEGER NOT NULL,
        made_at TEXT NOT NULL
    );
    CREATE INDEX fetches_by_day ON fetches(household, day, step);
    CREATE TABLE day_scores (
        household TEXT NOT NULL REFERENCES households(name),
        day TEXT NOT NULL,
        predictions INTEGER NOT NULL DEFAULT 0,
        correct INTEGER NOT NULL DEFAULT 0,
        fetches INTEGER NOT NULL DEFAULT 0,
        useful_fetches INTEGER NOT NULL DEFAULT 0,
        uses INTEGER NOT NULL DEFAULT 0,
        uses_fetched INTEGER NOT NULL DEFAULT 0,
        PRIMARY KEY (household, day)
    );
    CREATE TABLE settings (
        key TEXT PRIMARY KEY,
        value TEXT NOT NULL
    );
    """,
    # 5: a fetch already counted in day_scores (a long gap restarts the day: the fetches before it
    # are settled then, and a rebuild must not count them again)
    """
    ALTER TABLE fetches ADD COLUMN settled INTEGER NOT NULL DEFAULT 0;
    """,
    # 6: the date of an uploaded training day, when the client gave it (ISO 8601; NULL: not known):
    # models that know the day of the week count it
    """
    ALTER TABLE training_days ADD COLUMN date TEXT;
    """,
    # 7: what a household runs (JSON): its grid (step, day start, steps a day), its deployment (the
    # models its cross-validation chose) and whether it learns new activities. NULL (households
    # stored before): taken from the training days and chosen again on first build.
    """
    ALTER TABLE households ADD COLUMN settings TEXT;
    """,
    # 8: a home's ambient sensors (activity recognition): the household's sensor list (JSON rows of
    # sensors.csv; NULL: no sensors), each training day's activations (its events CSV, compressed as
    # the days are; NULL: not recorded) and the activations an observation carried (JSON; NULL: none)
    """
    ALTER TABLE households ADD COLUMN sensors TEXT;
    ALTER TABLE training_days ADD COLUMN events BLOB;
    ALTER TABLE observations ADD COLUMN sensors TEXT;
    """,
    # 9: beside each day's one-step predictions scored, the steps persistence and hour + activity
    # got right (the rules the model must beat) and the steps they were scored at (0 for days
    # scored before: their rates leave those days out rather than count them wrong)
    """
    ALTER TABLE day_scores ADD COLUMN baseline_predictions INTEGER NOT NULL DEFAULT 0;
    ALTER TABLE day_scores ADD COLUMN persistence_correct INTEGER NOT NULL DEFAULT 0;
    ALTER TABLE day_scores ADD COLUMN hour_activity_correct INTEGER NOT NULL DEFAULT 0;
    """,
]
SCHEMA_VERSION = len(MIGRATIONS)


# a node as stored: dataclasses.asdict's keys, without its deep copies


@dataclass(frozen=True, slots=True)
class HouseholdRow:
    name: str
    timezone: str
    created_at: dt.datetime  # aware (UTC)
    problem: str | None = None  # why the stored row cannot be read (the household is then served as failed)
    shadow: bool = False  # predicts and scores itself, but never tells the robot to act


@dataclass(frozen=True, slots=True)
class FoundObservation:
    """A stored observation found by its client id: its acknowledgement and what it said."""

    id: int
    ack: dict
    time: str
    activity: str | None
    locations: str  # JSON, keys sorted


@dataclass(frozen=True, slots=True)
class StoredDay:
    """A stored training day: its text and its date (ISO 8601; None: not given), and its sensor
    activations' events CSV (None: not recorded)."""

    text: str
    date: str | None
    events: str | None = None


@dataclass(frozen=True, slots=True)
class StoredObservation:
    id: int
    time: str
    activity: str | None
    locations: str  # JSON
    received_at: str
    sensors: str | None = None  # JSON: [[sensor, start, end], ...] (ISO times), or None


@dataclass(frozen=True, slots=True)
class StepPrediction:
    """GLOBE's one-step-ahead prediction for a step, made before the step was observed."""

    step: int
    activity: str
    probability: float
    observed: str | None  # the step's activity once the step closed (None: not yet, or unknown)


@dataclass(frozen=True, slots=True)
class FetchRow:
    """A fetch GLOBE decided (in shadow mode too: then the robot was not told)."""

    day: str
    step: int
    object: str
    to_location: str | None
    probability: float | None
    shadow: bool
    made_at: str


@dataclass(frozen=True, slots=True)
class DayScore:
    """One day's online scores: counts, so that days add up."""

    day: str
    predictions: int = 0
    correct: int = 0
    fetches: int = 0
    useful_fetches: int = 0
    uses: int = 0
    uses_fetched: int = 0
    baseline_predictions: int = 0
    persistence_correct: int = 0
    hour_activity_correct: int = 0


SCORE_COLUMNS = ("predictions", "correct", "fetches", "useful_fetches", "uses", "uses_fetched", "baseline_predictions",
                 "persistence_correct", "hour_activity_correct")


@dataclass(frozen=True, slots=True)
class TokenRow:
    id: str
    household: str | None
    admin: bool
    created_at: str
    revoked_at: str | None
