"""Fit the Kilobot step-time cost model to the measured cycles, and test it on held-out scripts.

Design: reads kilobot_cycles.csv (one row per measured control step: the cycles simavr counted
on the reference VM, and the model's exact counts for the same step), fits

    cycles = per_step + per_instruction * I + per_gc_slot * (G * S) + per_message * M

by least squares on the rows whose role is "train", then prints the coefficients (those of
`bbzide.vm.steptime.KILOBOT`) and, per held-out script, the mean measured and predicted cycles
and the error. README.md in this folder says how the CSV was measured.

    .venv/bin/python benchmarks/steptime/fit.py
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

CSV = Path(__file__).with_name("kilobot_cycles.csv")
COEFFICIENTS = ("per_step", "per_instruction", "per_gc_slot", "per_message")


def load(path: Path = CSV) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(row for row in f if not row.startswith("#")))


def features(rows: list[dict[str, str]]) -> np.ndarray:
    return np.array([[1.0, float(r["instructions"]), float(r["gc_slots"]),
                      float(r["messages"])] for r in rows])


def fit(rows: list[dict[str, str]]) -> dict[str, float]:
    train = [r for r in rows if r["role"] == "train"]
    cycles = np.array([float(r["cycles"]) for r in train])
    solution, *_ = np.linalg.lstsq(features(train), cycles, rcond=None)
    return dict(zip(COEFFICIENTS, (float(x) for x in solution), strict=True))


def predict(coefficients: dict[str, float], rows: list[dict[str, str]]) -> np.ndarray:
    return features(rows) @ np.array([coefficients[name] for name in COEFFICIENTS])


def errors_by_script(coefficients: dict[str, float], rows: list[dict[str, str]],
                     role: str) -> dict[str, tuple[float, float, float]]:
    """script -> (mean measured cycles, mean predicted cycles, largest per-step error in %)."""
    result = {}
    for script in sorted({r["script"] for r in rows if r["role"] == role}):
        mine = [r for r in rows if r["script"] == script]
        measured = np.array([float(r["cycles"]) for r in mine])
        predicted = predict(coefficients, mine)
        worst = float(np.max(np.abs(predicted - measured) / measured)) * 100
        result[script] = (float(measured.mean()), float(predicted.mean()), worst)
    return result


def main() -> None:
    rows = load()
    coefficients = fit(rows)
    print("coefficients (cycles):")
    for name, value in coefficients.items():
        print(f"  {name} = {value:.1f}")
    for role in ("train", "heldout"):
        print(f"\n{role}: script, mean measured cycles, mean predicted, error of the mean, "
              "worst step")
        for script, (measured, predicted, worst) in errors_by_script(
                coefficients, rows, role).items():
            print(f"  {script:<28} {measured:>11.0f} {predicted:>11.0f} "
                  f"{(predicted - measured) / measured * 100:+6.1f} % {worst:6.1f} %")


if __name__ == "__main__":
    main()
