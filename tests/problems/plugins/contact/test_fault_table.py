"""The fault table, assembly half (README "What catches which fault"; the solver half is in
tests/problems/commands/test_check.py): a fault in the assembled blocks reaches every solver
alike, so `mixvi check` cannot see it; each fault below is injected with monkeypatch and the
check that must catch it is asserted to fail, after asserting that it passes without the fault.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse

import fem.assembly
import fem.mortar
from problems.commands.main import main
from problems.plugins.contact import curve_contact, rows

from . import checks

# ------------------------------------------------------------------ the faults
_coupling = fem.assembly.coupling_matrix
_mortar = fem.mortar.mortar_coupling
_friction = curve_contact.friction_local
_dual_mass = rows.dual_mass


def coupling_sign(mp):
    """G → −G: A = [[K, −Gᵀ], [G, P]] (the sign convention of eᵀ∇φ flipped)."""
    mp.setattr(fem.assembly, "coupling_matrix", lambda mesh, e: -_coupling(mesh, e))


class _TransposedLowerBlock:
    """scipy.sparse whose bmat builds the φ-row block as the TRANSPOSE of the u-row coupling
    block, [[K, Gᵀ], [(Gᵀ)ᵀ, P]], instead of its negative transpose."""

    def __getattr__(self, name):
        return getattr(scipy.sparse, name)

    def bmat(self, blocks, **kw):
        if len(blocks) == 2 and blocks[1][0] is not None and blocks[0][1] is not None:
            blocks = [blocks[0], [blocks[0][1].T, blocks[1][1]]]
        return scipy.sparse.bmat(blocks, **kw)


def coupling_transpose(mp):
    mp.setattr(fem.assembly, "sp", _TransposedLowerBlock())  # piezo_matrix's bmat


def mortar_dropped_entry(mp):
    """The largest entry of a middle row of M dropped (set to 0)."""

    def faulty(*args, **kw):
        mo = _mortar(*args, **kw)
        M = mo.M.tolil()
        i = M.shape[0] // 2
        j = int(np.argmax(np.abs(M[i].toarray())))
        M[i, j] = 0.0
        return dataclasses.replace(mo, M=M.tocsr())

    mp.setattr(fem.mortar, "mortar_coupling", faulty)
    from tests.fem import test_mortar

    mp.setattr(test_mortar, "mortar_coupling", faulty)


def friction_bound(mp):
    """∫gφ_i × 1.5: the friction bound of every node 50 % too high."""
    mp.setattr(curve_contact, "friction_local", lambda *a, **k: 1.5 * _friction(*a, **k))


def dual_weight(mp):
    """∫ψ_{e,a}φ_a of the two end nodes of Γ3 = the whole end segment's length, not half."""

    def faulty(tr):
        D = _dual_mass(tr).tocsr(copy=True)  # (2 n_seg, k), one entry per row
        D.data[[0, -1]] *= 2.0
        return D

    mp.setattr(rows, "dual_mass", faulty)


# ------------------------------------------------------------------ the checks
def manufactured_rates_hold() -> bool:
    return not checks.rates_off(checks.manufactured_rates(), checks.MANUFACTURED_RATES)


def mortar_patch_test_holds() -> bool:
    from tests.fem import test_mortar

    try:
        test_mortar.test_tied_patch_test_keep_reproduces_a_vertical_linear_field(0)
    except AssertionError:
        return False
    return True


def curved_rates_hold() -> bool:
    return not checks.rates_off(checks.curved_rates(), checks.CURVED_RATES)


def balance_holds(name: str, level: int) -> bool:
    return checks.force_imbalance(name, level) <= checks.BALANCE_OK


def lemma_holds() -> bool:
    return checks.lemma_gap("rigid_foundation", 1) <= checks.LEMMA_OK


FAULT_TABLE = [  # (fault, check name, check) — one row of the README table each
    (coupling_sign, "manufactured rates", manufactured_rates_hold),
    (coupling_transpose, "manufactured rates", manufactured_rates_hold),
    (mortar_dropped_entry, "mortar patch test", mortar_patch_test_holds),
    (mortar_dropped_entry, "curved two-body exact rates", curved_rates_hold),
    (
        mortar_dropped_entry,
        "force balance (two bodies)",
        lambda: balance_holds("paper_two_body", 1),
    ),
    (friction_bound, "Lemma 4.2 by quadrature", lemma_holds),
    (friction_bound, "manufactured rates", manufactured_rates_hold),
    (dual_weight, "force balance (rigid)", lambda: balance_holds("rigid_foundation", 1)),
    (dual_weight, "manufactured rates", manufactured_rates_hold),
]
IDS = [f"{f.__name__}->{name}" for f, name, _ in FAULT_TABLE]


@pytest.mark.parametrize(("fault", "name", "check"), FAULT_TABLE, ids=IDS)
def test_check_catches_fault(fault, name, check, monkeypatch):
    assert check(), f"{name} must pass without the fault"
    fault(monkeypatch)
    assert not check(), f"{name} did not catch {fault.__name__}"


def test_assembly_faults_pass_the_cross_check(monkeypatch, tmp_path):
    """Why the table needs more than `mixvi check`: with the coupling sign flipped, ssn,
    homotopy and conic solve the same wrong problem and agree."""
    coupling_sign(monkeypatch)
    assert main(["check", "manufactured", "--level", "1"]) == 0
