"""The inexact Newton forcing terms (`vi_core.forcing`)."""

import pytest

from vi_core import forcing


def test_forcing_term():
    assert forcing.forcing_term(1.0, None, 1e-10) == forcing.ETA_MAX
    # fast convergence: η follows 0.9 (F_k / F_{k−1})²
    assert forcing.forcing_term(1e-4, 1e-1, 1e-16) == pytest.approx(0.9e-6)
    # never more accurate than reaching tol needs
    assert forcing.forcing_term(1e-6, 1e-3, 1e-10) == pytest.approx(0.1 * 1e-10 / 1e-6)
    # slow convergence: capped
    assert forcing.forcing_term(0.5, 1.0, 1e-10) == forcing.ETA_MAX
    # a warm start: every step solved to the floor of tol, also below a cap
    assert forcing.ETA_MAX_WARM == 0.0
    assert forcing.forcing_term(0.5, 1.0, 1e-10, forcing.ETA_MAX_WARM) == pytest.approx(
        0.1 * 1e-10 / 0.5
    )
    assert forcing.forcing_term(1e-6, 1e-3, 1e-10, 1e-8) == pytest.approx(0.1 * 1e-10 / 1e-6)
