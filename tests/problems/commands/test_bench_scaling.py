"""The fitted exponents of `mixvi bench` records and the scaling figure."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from problems.commands import bench_scaling


def _records(rng, b_time, b_mem, solver="amg", scene="s", n0=1000.0):
    sizes = n0 * 4.0 ** np.arange(4)
    noise = np.exp(rng.uniform(-0.01, 0.01, (3, sizes.size)))
    return [
        {
            "scene": scene,
            "level": i,
            "unknowns": int(n),
            "solver": "ssn",
            "converged": True,
            "linear_solver": solver,
            "time_nonlinear_s": 2e-5 * n**b_time * noise[0, i],
            "time_linear_s": 1e-5 * n**b_time * noise[1, i],
            "peak_mem_mb": 1e-3 * n**b_mem * noise[2, i],
        }
        for i, n in enumerate(sizes)
    ]


@given(
    seed=st.integers(0, 2**32 - 1),
    b_time=st.floats(0.5, 2.0),
    b_mem=st.floats(0.5, 1.5),
)
def test_fits_recover_the_exponents_of_power_laws(seed, b_time, b_mem):
    rng = np.random.default_rng(seed)
    recs = _records(rng, b_time, b_mem) + _records(rng, 1.0, 1.0, solver="splu")
    fits = {f["linear_solver"]: f["exponent"] for f in bench_scaling.fits(recs)}
    assert set(fits) == {"amg", "splu"}
    # multiplicative noise ≤ 1 % over a factor 64 in N moves a slope by ≤ 0.02/ln 64 ≈ 0.005
    assert abs(fits["amg"]["time_nonlinear"] - b_time) < 0.01
    assert abs(fits["amg"]["time_linear"] - b_time) < 0.01
    assert abs(fits["amg"]["peak_mem"] - b_mem) < 0.01
    assert abs(fits["splu"]["peak_mem"] - 1.0) < 0.01


def test_failed_and_unconverged_rows_are_left_out_of_the_fit():
    """Mutation: a failed row with a tiny time would pull the slope (here to about 0.3)."""
    recs = _records(np.random.default_rng(1), 1.2, 1.0)
    bad = dict(recs[-1], unknowns=recs[-1]["unknowns"] * 4, time_nonlinear_s=1e-3)
    (fit,) = bench_scaling.fits([*recs, {**bad, "error": "killed"}, {**bad, "converged": False}])
    assert abs(fit["exponent"]["time_nonlinear"] - 1.2) < 0.01
    (mutant,) = bench_scaling.fits([*recs, bad])
    assert abs(mutant["exponent"]["time_nonlinear"] - 1.2) > 0.3


def test_one_size_has_no_fit_and_the_figure_still_draws():
    recs = _records(np.random.default_rng(2), 1.0, 1.0)[:1]
    assert bench_scaling.fits(recs) == []
    svg = bench_scaling.figure_svg(recs)
    assert "</svg>" in svg


def test_figure_names_every_series_with_its_exponent():
    rng = np.random.default_rng(3)
    recs = _records(rng, 1.05, 0.98) + _records(rng, 1.5, 1.2, solver="splu")
    svg = bench_scaling.figure_svg(recs)
    assert "s amg nonlinear (N^1.05)" in svg and "s splu nonlinear (N^1.50)" in svg
