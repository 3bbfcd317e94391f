"""Training days as the store keeps them: their CSV text, zlib-compressed (a tenth of the size),
read back exactly; and days stored by schema 1-2 as JSON."""

from __future__ import annotations

import itertools
import json
import zlib
from typing import Sequence

from globe.data.records import Day


def encode_day(text: str) -> bytes:
    return zlib.compress(text.encode("utf-8"), 1)


class DayEncoding:
    """:func:`encode_day` of each of ``day_texts``, shared by the threads that call :meth:`run`:
    each call compresses days no other call has taken, so a thread that would wait for a helper
    helps it instead. A helper started before other work gets little done while that work holds
    the GIL (it needs the GIL back after every day); the days left are then compressed by both
    threads at once. The blobs are the same whoever made them."""

    def __init__(self, day_texts: Sequence[str]) -> None:
        self._texts = list(day_texts)
        self._taken = itertools.count()  # next() is atomic: each day goes to one thread
        self.blobs: list[bytes] = [b""] * len(self._texts)
        self._stopped = False

    def run(self) -> None:
        for i in self._taken:
            if i >= len(self._texts) or self._stopped:
                return
            self.blobs[i] = encode_day(self._texts[i])

    def stop(self) -> None:
        """Take no more days (the blobs are then incomplete): the household will not be stored."""
        self._stopped = True


def decode_day(stored: bytes | str) -> str:
    """A stored day's text; a damaged blob becomes "" (then refused, logged and set aside by the loader)."""
    if not isinstance(stored, bytes):
        return stored
    try:
        return zlib.decompress(stored).decode("utf-8")
    except (zlib.error, UnicodeDecodeError):
        return ""


def legacy_day(payload: str) -> Day:
    """A day stored by schema 1-2 (a JSON-encoded :class:`Day`)."""
    d = json.loads(payload)
    locations = tuple(tuple(s) for s in d["locations"])
    return Day(d["name"], tuple(d["minutes"]), tuple(d["activities"]), locations, d.get("source", ""))
