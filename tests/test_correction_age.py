"""The correction-age study's bookkeeping (studies/correction_age.py; docs/studies/correction-age.md):
the ages of a stepped protocol's segments, and the Boltzmann age of a history that is itself one
ramp, which must be that ramp's age whatever the cortex's exponent and memory."""

import math

import pytest

from solver.protocol import Protocol
from studies.correction_age import _timeline, boltzmann_age


def test_a_segments_age_counts_its_wait_and_the_oscillations_before_it():
    protocol = Protocol.stepped(20.0, (13.0, 12.0), (0.5, 5.0), (4, 10), wait_s=100.0, speed_um_per_s=0.2)
    ramps, oscillations = _timeline(protocol)
    assert ramps == [(0.0, 35.0, 7.0), pytest.approx((145.0, 150.0, 1.0))]
    ages = [age for age, _, _ in oscillations]
    assert ages == pytest.approx([100.0 + 4.0, 100.0 + 8.0 + 1.0] * 2)     # 8 s at 0.5 Hz, then 2 s at 5 Hz


@pytest.mark.parametrize("beta, memory_s", [(0.2, math.inf), (0.1, 30.0), (0.4, 10.0)])
def test_one_ramp_is_its_own_boltzmann_age(beta, memory_s):
    protocol = Protocol.stepped(20.0, (13.0,), (1.0,), (5,), wait_s=60.0)
    ramps, ((age, middle, _),) = _timeline(protocol)
    assert boltzmann_age(ramps, middle, 7.0, 0.2, beta, memory_s) == pytest.approx(age, rel=1e-6)


def test_an_older_step_makes_the_history_older_than_the_last_ramp():
    protocol = Protocol.stepped(20.0, (13.0, 12.0), (1.0,), (5,), wait_s=60.0)
    ramps, oscillations = _timeline(protocol)
    age, middle, _ = oscillations[1]
    a_b = boltzmann_age(ramps, middle, 8.0, 0.2, 0.2, math.inf)
    assert a_b > age        # most of the depth was reached 65 s earlier
