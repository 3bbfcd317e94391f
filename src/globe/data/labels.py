"""The one rule for an activity label a household is told (over HTTP, from Home Assistant over
MQTT, on the command line): a valid label (:func:`globe.data.csv_logs.activity_label`) that the
household knows, or, where it learns new activities, any valid label.

An unknown label is refused with the known ones listed; one that differs from a known label only
in case, spaces, '_' or '-' (``relax`` for ``Relax``, ``wash dishes`` for ``wash_dishes``) is named
as that label's variant, since starting a new activity for a typo would split the routine in two.
"""

from __future__ import annotations

import re
from typing import Collection

from globe.data.csv_logs import activity_label
from globe.errors import UnknownLabelError

SHOWN = 40  # known labels listed in a message
_SEPARATORS = re.compile(r"[\s_\-]+")


def label_key(label: str) -> str:
    """What a label's case and spacing variants share: casefolded, spaces, '_' and '-' as one '_'."""
    return _SEPARATORS.sub("_", label.casefold()).strip("_")


def known_activity(raw: str, known: Collection[str], *, learn: bool = False, field: str = "activity") -> str:
    """``raw`` as a valid label, if ``known`` holds it or ``learn`` is set; else an
    :class:`UnknownLabelError` naming the variant it resembles, or listing the known labels."""
    label = activity_label(raw, field=field)
    if label in known or learn:
        return label
    shown = repr(label[:64]) + ("..." if len(label) > 64 else "")
    variants = sorted(k for k in known if label_key(k) == label_key(label))
    if variants:
        raise UnknownLabelError(f"unknown activity {shown}: a case or spacing variant of the known "
                                f"{' and '.join(map(repr, variants))}; send the label as it is known", field=field)
    listed = sorted(known)
    more = f", ... ({len(listed)} in all)" if len(listed) > SHOWN else ""
    raise UnknownLabelError(f"unknown activity {shown}; known: {', '.join(listed[:SHOWN]) or 'none'}{more}",
                            field=field)
