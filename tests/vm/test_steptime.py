"""The step-time cost models: the Kilobot's coefficients are the fit of the measured cycles,
they predict the held-out scripts, and the Crazyflie's follow from them by the stated ratio."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from bbzide.vm.steptime import (
    CORTEX_M4_CYCLE_RATIO,
    CRAZYFLIE,
    KILOBOT,
    StepCounts,
    cost_model,
)

FIT = Path(__file__).resolve().parents[2] / "benchmarks" / "steptime" / "fit.py"


def _fit_module():  # noqa: ANN202 - a module
    spec = importlib.util.spec_from_file_location("steptime_fit", FIT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_kilobot_coefficients_are_the_fit_of_the_measured_cycles() -> None:
    fit = _fit_module()
    coefficients = fit.fit(fit.load())
    for name, value in coefficients.items():
        assert getattr(KILOBOT, name) == pytest.approx(value, rel=1e-3, abs=1.0), name


def test_held_out_scripts_are_predicted_within_ten_percent() -> None:
    fit = _fit_module()
    rows = fit.load()
    held_out = fit.errors_by_script(fit.fit(rows), rows, "heldout")
    assert len(held_out) >= 3
    for script, (measured, predicted, worst) in held_out.items():
        assert abs(predicted - measured) / measured < 0.10, script
        assert worst < 12.0, script


def test_crazyflie_is_the_kilobot_scaled_by_ratio_and_clock() -> None:
    counts = StepCounts(instructions=50, gc_runs=56, gc_slots=5600.0, messages=3)
    assert CRAZYFLIE.cycles(counts) == pytest.approx(KILOBOT.cycles(counts)
                                                     * CORTEX_M4_CYCLE_RATIO)
    ratio = KILOBOT.milliseconds(counts) / CRAZYFLIE.milliseconds(counts)
    assert ratio == pytest.approx(168 / 8 / CORTEX_M4_CYCLE_RATIO)
    assert CRAZYFLIE.uncertainty > 1.0 and KILOBOT.uncertainty == 1.0


def test_more_work_costs_more_and_unknown_platforms_have_no_model() -> None:
    small = StepCounts(instructions=10, gc_runs=10, gc_slots=900.0, messages=0)
    big = StepCounts(instructions=100, gc_runs=100, gc_slots=9000.0, messages=2)
    assert KILOBOT.milliseconds(big) > KILOBOT.milliseconds(small) > 0
    assert cost_model("kilobot") is KILOBOT
    assert cost_model("m300") is None
