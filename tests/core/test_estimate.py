"""The time and memory estimate of a construction, and the refusal of one that will not fit."""
import numpy as np
import pytest

from core.mesh import primitives
from core.construct import construct
from core.construct import run as run_module
from core.construct.estimate import check_fits, estimate
from core.construct.types import ConstructError
from core.mesh.trimesh import TriMesh
from core.runtime.machine import available_memory_bytes, peak_resident_bytes
from core.settings.fields import preset


def test_the_estimate_grows_with_the_input_and_the_budget():
    s = preset("default")
    small, big = estimate(100_000, s, speed=1.0), estimate(1_000_000, s, speed=1.0)
    assert 0 < small.seconds < big.seconds and 0 < small.peak_bytes < big.peak_bytes
    # two per input face as micromesh-tools counts them: a tenth more than nominal, as a rule
    assert small.micro_triangles == 220_000 and big.micro_triangles == 2_200_000
    assert set(small.phases) == {"input", "base", "optimize", "fit", "polish", "metrics"}
    assert estimate(100_000, preset("paper"), speed=1.0).phases["polish"] == 0
    half = estimate(1_000_000, preset("default", budget_ratio=1.0), speed=1.0)
    assert half.peak_bytes < big.peak_bytes and half.micro_triangles == 1_100_000
    exact = estimate(1_000_000, preset("default", budget_ratio=0,
                                       budget_micro_triangles=2_000_000), speed=1.0)
    assert exact.micro_triangles == 2_000_000
    assert "GB of memory for 2,000,000 micro-triangles" in exact.text()


def test_times_scale_with_the_machine_speed_and_memory_does_not():
    s = preset("default", time_limit_s=0.0)
    ref, fast = estimate(300_000, s, speed=1.0), estimate(300_000, s, speed=2.0)
    assert fast.seconds == pytest.approx(ref.seconds / 2)
    assert fast.phases["fit"] == pytest.approx(ref.phases["fit"] / 2)
    assert fast.peak_bytes == ref.peak_bytes
    # The time limit is wall time, from the base building to the metrics: the loop gets what
    # the rest leaves of 90 % of it, so a slower machine optimises less within the same
    # limit...
    limited = preset("default", time_limit_s=200.0)
    for speed in (1.0, 0.9):
        e = estimate(800_000, limited, speed=speed)
        free = estimate(800_000, s, speed=speed)
        assert e.seconds == pytest.approx(3.0 / speed + e.phases["input"] + 0.9 * 200.0)
        assert e.seconds < free.seconds
    # ...and where the base, the fit's first round and bounds (half its estimate) and the
    # metrics alone take longer, the loop only subdivides (about 10 iterations each).
    slow = estimate(1_000_000, preset("default", time_limit_s=60.0), speed=0.25)
    least = slow.phases["input"] + slow.phases["base"] + 0.5 * slow.phases["fit"] + \
        slow.phases["metrics"] + 3.0 / 0.25
    assert least > 60.0 and least < slow.seconds < least + 0.5 * slow.phases["optimize"]


def test_the_machine_speed_is_probed_once_and_is_a_plain_number():
    from core.runtime import speed

    first = speed.machine_speed()
    assert 0.05 <= first <= 20.0 and speed.machine_speed() == first
    assert 0.0 < speed.probe_seconds() < 5.0
    assert estimate(100_000, preset("default")).seconds == pytest.approx(
        estimate(100_000, preset("default"), speed=first).seconds)


def test_a_run_that_will_not_fit_is_refused_with_the_estimate():
    guess = estimate(2_000_000, preset("default"))
    check_fits(guess, None)                              # the platform does not say: run
    check_fits(guess, guess.peak_bytes * 1.01)
    with pytest.raises(ConstructError) as e:
        check_fits(guess, guess.peak_bytes / 4)
    msg = str(e.value)
    half = guess.micro_triangles // 2
    assert guess.text() in msg and f"budget_micro_triangles={half}" in msg
    assert f"--budget {half}" in msg


def test_construct_refuses_before_any_work_when_memory_is_short(monkeypatch):
    v, f = primitives.icosphere(3)
    monkeypatch.setattr(run_module, "available_memory_bytes", lambda: 100 * 2 ** 20)
    called = []
    with pytest.raises(ConstructError, match="only 0.1 GB are available"):
        construct(TriMesh(v, f), None, None, preset("fast"), progress=called.append)
    assert called == []                                  # not even the base was started


def test_this_machine_says_what_it_has():
    assert available_memory_bytes() > 2 ** 26
    assert peak_resident_bytes() > 2 ** 24
    assert np.isfinite(available_memory_bytes())
