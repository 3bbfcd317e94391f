"""One exception hierarchy for GLOBE: every front end catches :class:`GlobeError`.

Each class carries the HTTP status the service answers it with (``http_status``, inherited;
500 for the root: an error the service did not expect) and any headers that answer needs, so the
service maps errors to responses in one handler without knowing the classes.
"""

from __future__ import annotations

from typing import ClassVar


class GlobeError(Exception):
    """Root of every error GLOBE raises on purpose."""

    http_status: ClassVar[int] = 500
    http_headers: ClassVar[dict[str, str]] = {}
    field: str | None = None  # the input that is wrong, where known


class ConfigError(GlobeError, ValueError):
    """A configuration value is missing, malformed or out of range."""

    http_status = 422


class DataError(GlobeError, ValueError):
    """Bad input data; names the file (``source``), ``line`` and ``field`` where known.

    Formatted like a compiler message so editors link it:
    ``HouseholdA/train/012.csv:57: column 'minute': 610 is not after 620``.
    """

    http_status = 422

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.message = message
        self.source = source
        self.line = line
        self.field = field
        super().__init__(self._format())

    def _format(self) -> str:
        where = ""
        if self.source is not None:
            where = str(self.source)
            if self.line is not None:
                where += f":{self.line}"
            where += ": "
        what = f"column {self.field!r}: " if self.field is not None else ""
        return f"{where}{what}{self.message}"


class UnknownLabelError(DataError):
    """A label (activity, object, location) the model or home does not know."""


class NotFittedError(GlobeError, ValueError, AttributeError):
    """A model was asked to predict before ``fit`` was called."""


class ModelFileError(GlobeError, ValueError):
    """A saved model file is unreadable or of another format version."""


class LLMError(GlobeError):
    """An LLM backend gave no usable answer. Only the gate catches it (and falls back)."""

    http_status = 503


class LLMUnavailableError(LLMError):
    """The backend could not be reached or loaded."""


class LLMTimeoutError(LLMUnavailableError):
    """The backend did not answer in time."""


class LLMAnswerError(LLMError):
    """The backend answered, but not with one of the listed candidates."""

    def __init__(self, message: str, *, raw: str | None = None) -> None:
        self.raw = raw
        super().__init__(message)


class MissingExtraError(GlobeError, ImportError):
    """An optional dependency is not installed; the message gives the pip command."""

    def __init__(self, package: str, extra: str) -> None:
        super().__init__(
            f"{package} is not installed; install it with: pip install \"globe[{extra}]\""
        )


class StoreError(GlobeError):
    """The service's database failed."""

    http_status = 503


class LLMCacheError(LLMError):
    """The on-disk answer cache failed (locked, missing, corrupt): the gate falls back to the n-gram."""

    reason: str | None = None  # 'locked', 'missing', 'corrupt', ... where the cache knows it


class AuthenticationError(GlobeError):
    """No credentials, or credentials the service does not know (HTTP 401)."""

    http_status = 401
    http_headers = {"WWW-Authenticate": "Bearer"}
    field = "authorization"


class PermissionDeniedError(GlobeError):
    """Valid credentials that do not reach this resource (HTTP 403)."""

    http_status = 403
    field = "authorization"


class LimitError(DataError):
    """A request exceeds a configured limit; ``field`` names what is too large."""


class StoreUnavailableError(StoreError):
    """The database file disappeared or was replaced while the service ran: writes are refused."""


class UnknownHouseholdError(GlobeError, KeyError):
    """The service holds no household of that name (HTTP 404)."""

    http_status = 404

    def __init__(self, name: str) -> None:
        super().__init__(f"unknown household {name!r}")
        self.name = name

    def __str__(self) -> str:
        return str(self.args[0])


class DuplicateHouseholdError(GlobeError):
    """A household of that name exists already (HTTP 409)."""

    http_status = 409
    field = "name"


class HouseholdUnavailableError(StoreError):
    """A stored household cannot be built from its rows (damaged, or written by another GLOBE):
    it answers 503 with the reason, and can still be deleted or exported."""


class DuplicateObservationError(GlobeError):
    """An observation id the household already acknowledged for a different observation (HTTP 409)."""

    http_status = 409
    field = "id"


class DamagedDatabaseError(StoreError):
    """The service's database file is empty or truncated: refused at start-up (``--new-db`` sets
    it aside and starts a new one)."""
