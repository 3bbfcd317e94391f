"""What every benchmark starts with: the command line (--data) and the HOMER+ households."""

from __future__ import annotations

import argparse

from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.data.records import Household


def setup(doc: str | None,
          extra: dict[str, dict] | None = None) -> tuple[GlobeConfig, list[Household], argparse.Namespace]:
    """Parse ``--data`` (and ``extra`` options), load every configured household."""
    parser = argparse.ArgumentParser(description=doc)
    parser.add_argument("--data", default=None, help="HOMER+ folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")
    for flag, kwargs in (extra or {}).items():
        parser.add_argument(flag, **kwargs)
    args = parser.parse_args()
    cfg = GlobeConfig()
    root = resolve_data_root(args.data)
    return cfg, [load_household(root, n) for n in cfg.data.households], args
