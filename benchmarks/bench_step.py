"""The step is a real choice: fitting, predicting and forecasting on 10-, 5- and 1-minute grids.

HOMER+ household A is resampled to each step (last observation carried forward, the
``data.resample = "locf"`` rule), so the routine is the same and only the number of steps
changes. Printed per step: the steps of the training days, the time to fit the routine model
and the object model, to predict the next activity at every step of the test days, and to
forecast the next hour (60 minutes = 60 / step steps) from every hour of the test days; then
each time per step, as a ratio to the 10-minute grid's. Target: the ratios stay near 1 (the
cost grows no faster than the number of steps; the forecast's grows with the steps of its hour
too, so its ratio is per step of forecast).
Usage: python benchmarks/bench_step.py [--data DIR] [--steps 10,5,1]
"""

from __future__ import annotations

import time

from common import setup
from globe import assembly
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root


def measure(step: int, root, cfg) -> dict[str, float]:
    home = load_household(root, "A", step_minutes=step, resample="locf")
    config = cfg.with_overrides({"models.activity_estimator": "routine", "data.step_minutes": step})
    started = time.perf_counter()
    fitted = assembly.fit_household(home, config)
    fit_s = time.perf_counter() - started
    started = time.perf_counter()
    for day in home.test:
        fitted.activity.scan_proba(day.activities)
    predict_s = time.perf_counter() - started
    forecaster = assembly.forecaster(home, config).forecaster
    horizon = 60 // step
    queries = [(day.activities[:r], day.locations[:r + 1]) for day in home.test
               for r in range(horizon, len(day) - horizon, horizon)]
    started = time.perf_counter()
    forecaster.forecast_many(queries, horizon)
    forecast_s = time.perf_counter() - started
    return {"train_steps": sum(len(d) for d in home.train), "test_steps": sum(len(d) for d in home.test),
            "fit_s": fit_s, "predict_s": predict_s, "forecast_s": forecast_s, "queries": len(queries),
            "horizon": horizon}


def main() -> None:
    cfg, _, args = setup(__doc__, {"--steps": {"default": "10,5,1", "help": "steps (minutes) to compare"}})
    root = resolve_data_root(args.data)
    results = {int(s): measure(int(s), root, cfg) for s in args.steps.split(",")}
    base = results[max(results)]
    print(f"{'step':>4s} {'train steps':>11s} {'fit s':>7s} {'predict s':>9s} {'forecast s':>10s} "
          f"{'fit/step':>9s} {'predict/step':>12s} {'forecast/step':>13s}")
    for step, r in results.items():
        fit = (r["fit_s"] / r["train_steps"]) / (base["fit_s"] / base["train_steps"])
        pred = (r["predict_s"] / r["test_steps"]) / (base["predict_s"] / base["test_steps"])
        per_query = r["forecast_s"] / (r["queries"] * r["horizon"])
        fore = per_query / (base["forecast_s"] / (base["queries"] * base["horizon"]))
        print(f"{step:4d} {r['train_steps']:11d} {r['fit_s']:7.3f} {r['predict_s']:9.3f} {r['forecast_s']:10.3f} "
              f"{fit:8.2f}x {pred:11.2f}x {fore:12.2f}x")


if __name__ == "__main__":
    main()
