"""The fetch source's cross-validation reads held-out days at once, not step by step.

For each HOMER+ household (10-minute steps, and household A resampled to 5 minutes) the
routine deployment's session is built on the first training days and the next ones are read
both ways: replayed step by step through the session (:func:`~globe.evaluation.fetch.replay_test_days`,
what the cross-validation did first) and forecast at once (:func:`~globe.evaluation.fetch.forecast_day`,
what it does now). Printed per household: the seconds per day of each, their ratio, and whether
the two gave the same candidates and fetches (they must). Then the whole choice
(:func:`~globe.evaluation.fetch_source.choose_fetch_source`) per household, in seconds.
Usage: python benchmarks/bench_fetch_source.py [--data DIR] [--days 10]
"""

from __future__ import annotations

import time
from dataclasses import replace

from common import setup
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.evaluation.anticipation import method_models
from globe.evaluation.fetch import LAST_DATE, forecast_day, replay_test_days
from globe.evaluation.fetch_source import choose_fetch_source, policy_deployment
from globe.evaluation.lookahead import choose_settings, setting_of
from globe.evaluation.online import replay_dates
from globe.evaluation.selection import Memo
from globe.session import build_session


def main() -> None:
    cfg, homes, args = setup(__doc__, {"--days": {"type": int, "default": 10, "help": "held-out days read"}})
    cfg = cfg.with_overrides({"llm.backend": "none"})
    resampled = load_household(resolve_data_root(args.data), "A", step_minutes=5, resample="locf")
    print(f"{'household':>9s} {'step':>4s} {'replay s/day':>12s} {'at once s/day':>13s} {'ratio':>7s} {'same':>5s} "
          f"{'choice s':>8s}")
    for home, step in [(h, 10) for h in homes] + [(resampled, 5)]:
        memo = Memo()
        models = method_models("routine", home, cfg, memo)
        setting = setting_of(choose_settings(home, cfg, models, memo).best)
        deployment = policy_deployment(cfg, models, setting)
        train, held_out = home.train[: -args.days], home.train[-args.days:]
        session = build_session(replace(home, train=train, test=held_out), cfg, deployment, None, learn=False)
        dates = replay_dates(held_out, LAST_DATE)
        started = time.perf_counter()
        replayed = replay_test_days(session, home, held_out)
        replay_s = (time.perf_counter() - started) / len(held_out)
        started = time.perf_counter()
        at_once = [forecast_day(session, home, day, date) for day, date in zip(held_out, dates)]
        once_s = (time.perf_counter() - started) / len(held_out)
        started = time.perf_counter()
        choose_fetch_source(home, cfg, models, setting, memo)
        choice_s = time.perf_counter() - started
        print(f"{home.name:>9s} {step:4d} {replay_s:12.3f} {once_s:13.3f} {replay_s / once_s:6.1f}x "
              f"{str(at_once == replayed):>5s} {choice_s:8.1f}")


if __name__ == "__main__":
    main()
