"""The time and memory estimate of a construction, and the refusal of one that will not fit."""
import numpy as np
import pytest

from core import primitives
from core.construct import construct
from core.construct import run as run_module
from core.construct.estimate import check_fits, estimate
from core.construct.types import ConstructError
from core.mesh import TriMesh
from core.runtime.machine import available_memory_bytes, peak_resident_bytes
from core.settings import preset


def test_the_estimate_grows_with_the_input_and_the_budget():
    s = preset("default")
    small, big = estimate(100_000, s), estimate(1_000_000, s)
    assert 0 < small.seconds < big.seconds and 0 < small.peak_bytes < big.peak_bytes
    assert small.micro_triangles == 200_000 and big.micro_triangles == 2_000_000
    assert set(small.phases) == {"base", "optimize", "fit", "metrics"}
    half = estimate(1_000_000, preset("default", budget_ratio=1.0))
    assert half.peak_bytes < big.peak_bytes and half.micro_triangles == 1_000_000
    assert "GB of memory for 2,000,000 micro-triangles" in big.text()


def test_a_run_that_will_not_fit_is_refused_with_the_estimate():
    guess = estimate(2_000_000, preset("default"))
    check_fits(guess, None)                              # the platform does not say: run
    check_fits(guess, guess.peak_bytes * 1.01)
    with pytest.raises(ConstructError) as e:
        check_fits(guess, guess.peak_bytes / 4)
    msg = str(e.value)
    assert guess.text() in msg and "budget_micro_triangles=2000000" in msg
    assert "--budget 2000000" in msg


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
