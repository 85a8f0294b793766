"""The adaptive loop (problems.pipeline.adaptive.adapt) and `mixvi solve --accuracy NUMBER`."""

import json
from pathlib import Path

import numpy as np
import pytest

from problems.commands.main import main
from problems.pipeline import adaptive
from problems.plugins.contact import error_estimate as ce
from problems.plugins.contact import plane as pc
from problems.scene import load_scene

SCENES = Path(__file__).resolve().parents[3] / "problems" / "scenes"
OPTIONS = {"method": "ssn", "tol": 1e-10}


class Recording:
    """piezo_contact, with the efficiency index of each cycle's estimate recorded."""

    def __init__(self):
        self.index: list[float] = []

    def __getattr__(self, name):
        return getattr(pc, name)

    def estimate(self, model, sol):
        ind = pc.estimate(model, sol)
        eta = {k: v.eta for k, v in ind.items()}
        self.index.append(ce.efficiency(eta, ce.energy_errors(model, sol)))
        return ind


def _adapt(name: str, accuracy: float, **kw):
    plugin = Recording()
    out = adaptive.adapt(
        plugin, load_scene(SCENES / f"{name}.toml"), accuracy, solve_options=OPTIONS, **kw
    )
    return plugin, *out


def test_loop_reaches_accuracy_with_efficient_estimates():
    """manufactured to 0.5: the estimate falls every cycle, the meshes grow locally (less
    than 4× per cycle), the efficiency index stays in [0.5, 5], the last cycle meets it."""
    plugin, model, sol, cycles, why = _adapt("manufactured", 0.5)
    rel = [c["relative"] for c in cycles]
    assert rel[-1] <= 0.5 < min(rel[:-1]) and "≤ 0.5" in why
    assert np.all(np.diff(rel) < 0)
    n = np.array([c["unknowns"] for c in cycles])
    assert np.all(n[1:] > n[:-1]) and np.all(n[1:] < 4 * n[:-1])
    assert all(0.5 <= i <= 5.0 for i in plugin.index), plugin.index
    assert all(c["errors"]["u_H1"] > 0 for c in cycles)
    assert model.bodies[0].mesh.cell_type == "triangle"


def test_loop_stops_at_the_size_limit():
    _, model, _, cycles, why = _adapt("manufactured", 1e-6, max_unknowns=300)
    assert "300 unknowns" in why and 4 * cycles[-1]["unknowns"] > 300
    assert cycles[-1]["relative"] > 1e-6


class Flipped(Recording):
    """Recording, with the index of each cycle's estimate with the flux term's sign flipped."""

    def __init__(self):
        super().__init__()
        self.flipped: list[float] = []

    def estimate(self, model, sol):
        eta = ce.indicators(pc.SCENE_MODEL, model, sol, flip="flux")
        self.flipped.append(ce.efficiency(eta, ce.energy_errors(model, sol)))
        return super().estimate(model, sol)


def test_efficiency_over_adaptive_cycles_unilateral():
    """unilateral_manufactured (separation, stick, slip; exact): the index over 6 cycles
    stays in [0.5, 5] (3.36–3.63); the mutation σ_h n − λ_h leaves it by the last cycle
    (3.63 → 5.41 at 568 unknowns)."""
    plugin = Flipped()
    scene = load_scene(SCENES / "unilateral_manufactured.toml")
    adaptive.adapt(plugin, scene, 1e-9, solve_options=OPTIONS, max_cycles=6)
    assert len(plugin.index) == 6
    assert all(0.5 <= i <= 5.0 for i in plugin.index), plugin.index
    assert plugin.flipped[-1] > 5.0, plugin.flipped


@pytest.mark.slow
def test_efficiency_over_adaptive_cycles_curved():
    """curved_manufactured (quadrilaterals split into triangles): the index over 4 cycles."""
    plugin, *_ = _adapt("curved_manufactured", 1e-6, max_cycles=4)
    assert all(0.5 <= i <= 5.0 for i in plugin.index), plugin.index


@pytest.mark.slow
@pytest.mark.parametrize("zone", [[], ["--contact-zone"]])
def test_cli_accuracy_number(tmp_path, capsys, zone):
    out = tmp_path / "run"
    assert main(["solve", "manufactured", "--accuracy", "0.7", *zone, "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["contact_zone"] is bool(zone)
    assert s["reached"] and s["cycles"][-1]["relative"] <= 0.7 and len(s["uniform"]) >= 2
    assert (out / "convergence.png").stat().st_size > 0 and (out / "estimate_block.vtu").exists()
    lines = capsys.readouterr().out.splitlines()
    assert sum(line.strip()[:1].isdigit() for line in lines) == len(s["cycles"])


@pytest.mark.parametrize("value", ["2", "0", "fastest"])
def test_cli_accuracy_refused(tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exit_:
        main(["solve", "manufactured", "--accuracy", value, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert "--accuracy" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def _paper_cycles():
    """Three cycles of the paper example (curved, non-matching Γ3), with the final meshes."""
    scene = load_scene(SCENES / "paper_two_body.toml")
    return adaptive.adapt(pc, scene, 1e-9, solve_options=OPTIONS, max_cycles=3)


def _on_the_arc(model) -> float:
    """The largest distance of a Γ3 node of either body from the circle."""
    return max(
        np.abs(
            np.linalg.norm(b.mesh.points[b.mesh.boundaries["contact"]] - [0.0, 1.5], axis=-1) - 1
        ).max()
        for b in model.bodies
    )


def test_paper_example_refines_onto_the_arc():
    """The paper example adapts (the loop passes the geometry's arcs as `project`): its new
    nodes on Γ3 lie on the circle, on both bodies, and every cycle solves."""
    model, _, cycles, why = _paper_cycles()
    assert len(cycles) == 3 and why == "3 cycles" and all(c["converged"] for c in cycles)
    assert cycles[-1]["contact_nodes"] > cycles[0]["contact_nodes"]
    assert _on_the_arc(model) < 1e-12


def test_mutation_without_the_curves_the_nodes_leave_the_arc(monkeypatch):
    """The fault of the last session (no `project` in the loop): new Γ3 nodes stay on the
    level-0 chords; the interface check refuses the rebuild, or the nodes are off the arc."""
    import fem.bisection

    plain = fem.bisection.refine_marked
    monkeypatch.setattr(
        fem.bisection,
        "refine_marked",
        lambda m, k, project=None, bisect=None: plain(m, k, bisect=bisect),
    )
    try:
        model = _paper_cycles()[0]
    except Exception as err:  # the interface check
        assert "contact" in str(err) or "master" in str(err), err
    else:
        assert _on_the_arc(model) > 1e-4


class Keeping:
    """A plug-in, keeping each cycle's (model, solution)."""

    def __init__(self, plugin):
        self.plugin, self.solved = plugin, []

    def __getattr__(self, name):
        return getattr(self.plugin, name)

    def estimate(self, model, sol):
        self.solved.append((model, sol))
        return self.plugin.estimate(model, sol)


def _touch_x(model, sol) -> tuple[np.ndarray, np.ndarray]:
    """(x of the slave's contact nodes, their touch mask)."""
    c = model.contact
    return c.slave.mesh.points[c.tr.nodes[c.rows_n], 0], model.contact_state(sol)["touch"]


@pytest.mark.parametrize("zone", [True, False])
def test_contact_zone_bisects_every_touching_segment(zone):
    """hertz, contact_zone=True: between the outermost touching nodes of cycle 1 the next
    mesh has 2k + 1 contact nodes for k + 1 (every segment split); without it (the mutation)
    the energy marking alone leaves some unsplit there (at cycle 0 it splits them all)."""
    from problems import pipeline

    loaded = pipeline.load(str(SCENES / "hertz.toml"))
    plugin = Keeping(loaded.plugin)
    adaptive.adapt(
        plugin,
        loaded.scene,
        1e-9,
        solve_options=OPTIONS,
        max_cycles=3,
        contact_zone=zone,
    )
    (m0, s0), (m1, s1) = plugin.solved[-2:]
    x0, t0 = _touch_x(m0, s0)
    lo, hi = x0[t0].min(), x0[t0].max()
    x1, _ = _touch_x(m1, s1)
    k = int(((x0 >= lo) & (x0 <= hi)).sum()) - 1
    split = int(((x1 >= lo) & (x1 <= hi)).sum()) == 2 * k + 1
    assert split == zone, (k, int(((x1 >= lo) & (x1 <= hi)).sum()))


def _loop_arguments(tmp_path, monkeypatch, options: list[str]) -> dict:
    """The keyword arguments `mixvi solve manufactured --accuracy 0.7 OPTIONS` gives the
    adaptive loop (the loop itself replaced by one that stops at once: this checks the wiring,
    test_cli_accuracy_number the run); the interrupted run leaves nothing behind."""
    seen = {}

    class Stop(Exception):
        pass

    def fake(*args, **kw):
        seen.update(kw)
        raise Stop

    monkeypatch.setattr(adaptive, "adapt", fake)
    out = tmp_path / "o"
    assert main(["solve", "manufactured", "--accuracy", "0.7", *options, "--out", str(out)]) != 0
    assert not out.exists()
    return seen


@pytest.mark.parametrize("zone", [[], ["--contact-zone"]])
def test_cli_contact_zone_reaches_the_loop(tmp_path, monkeypatch, zone):
    """`--contact-zone` is passed on as adapt(..., contact_zone=True), and only with it."""
    assert _loop_arguments(tmp_path, monkeypatch, zone)["contact_zone"] is bool(zone)


@pytest.mark.parametrize("hook", [True, False])
def test_contact_zone_function_extends_the_marks(hook):
    """contact_zone=FUNCTION: the function sees the Dörfler marks and its marks are the ones
    refined: marking every cell of every body gives cycle 1 the nodes of one uniform
    refinement of cycle 0's mesh; without the hook (the mutation) Dörfler alone gives fewer."""
    seen = []

    def everything(model, sol, meshes, marked):
        seen.append({n: m.copy() for n, m in marked.items()})
        return {n: np.ones(meshes[n].n_cells, dtype=bool) for n in marked}

    plugin = Keeping(pc)
    adaptive.adapt(
        plugin,
        load_scene(SCENES / "manufactured.toml"),
        1e-9,
        solve_options=OPTIONS,
        max_cycles=2,
        contact_zone=everything if hook else False,
    )
    (m0, _), (m1, _) = plugin.solved
    full = m0.bodies[0].mesh.refined_nodes(1) == m1.bodies[0].mesh.points.shape[0]
    assert full == hook
    if hook:  # it was given Dörfler's marks: a proper subset of the cells
        marks = seen[0][m0.bodies[0].name]
        assert 0 < marks.sum() < marks.size


def test_split_marks():
    """A bool value is the cells split into 4; integers 2, 1, 0 are split into 4, bisected
    once, neither; any other integer is refused."""
    b = np.array([True, False, True])
    red, once = adaptive.split_marks(b)
    assert red is b and once is None
    red, once = adaptive.split_marks(np.array([2, 1, 0, 1]))
    assert red.tolist() == [True, False, False, False]
    assert once.tolist() == [False, True, False, True]
    with pytest.raises(ValueError, match="0, 1, 2"):
        adaptive.split_marks(np.array([0, 3]))


@pytest.mark.parametrize("level", [1, 2])
def test_contact_zone_may_ask_for_one_bisection(level):
    """contact_zone=FUNCTION returning integers: every cell at 1 bisects each cell once (cycle
    1 gains one node per distinct refinement edge of cycle 0's labelled mesh), at 2 splits
    each into 4 (one uniform refinement's nodes). adapt dropping the bisections (the mutation)
    leaves cycle 1 with cycle 0's nodes at level 1 and fails."""
    from fem.bisection import _edges

    expect = {}

    def every(model, sol, meshes, marked):
        for n, mesh in meshes.items():
            codes, cell_edges = _edges(mesh.cells, mesh.n_nodes)
            new = np.unique(cell_edges[:, 0]).size if level == 1 else codes.size
            expect.setdefault(n, mesh.n_nodes + new)  # cycle 0's (the loop marks after 1 too)
        return {n: np.full(meshes[n].n_cells, level, dtype=np.int8) for n in marked}

    plugin = Keeping(pc)
    adaptive.adapt(
        plugin,
        load_scene(SCENES / "manufactured.toml"),
        1e-9,
        solve_options=OPTIONS,
        max_cycles=2,
        contact_zone=every,
    )
    (m0, _), (m1, _) = plugin.solved
    for body in m1.bodies:
        assert body.mesh.n_nodes == expect[body.name] > m0.bodies[0].mesh.n_nodes


@pytest.mark.slow
def test_separately_meshed_curved_interface_refines_to_tiny_cells():
    """wavy_two_body (two gmsh bodies along one curve, their polylines a sagitta apart) to a
    relative estimate of 0.02, as `mixvi solve wavy_two_body --accuracy 0.02` runs it: once
    stopped at cycle 6, its own refined interface refused as an "overlap" (the tolerance taken
    from the refined segments), then at cycle 18, a cell 2^-18 of its level-0 size at a
    singular corner refused as degenerate (against the mesh's extent). Now it runs to its cap."""
    plugin = pc
    scene = load_scene("wavy_two_body")
    model, sol, cycles, why = adaptive.adapt(
        plugin, scene, 0.02, max_unknowns=160_000, solve_options=OPTIONS
    )
    assert len(cycles) >= 20 and "could pass" in why and sol.converged
    assert all(c["converged"] for c in cycles)
    rel = [c["relative"] for c in cycles]
    assert rel[-1] < 0.7 * rel[0]


def test_a_solve_that_does_not_converge_stops_the_loop():
    """SSN held to 2 iterations on manufactured: cycle 0 does not converge, and the loop stops
    there and says so, instead of marking by an estimate that measures the solver's error
    too (signorini --accuracy 0.05: SSN at its 60 iterations from cycle 8 on, the
    complementarity term half of η², the estimate flat at 0.12 while contact nodes grew from
    159 to 4,518 over 10 more cycles and 300 s)."""
    scene = load_scene(SCENES / "manufactured.toml")
    _, sol, cycles, why = adaptive.adapt(
        pc, scene, 1e-6, solve_options={**OPTIONS, "max_iter": 2}, max_cycles=4
    )
    assert not sol.converged and len(cycles) == 1 and not cycles[0]["converged"]
    assert why.startswith("cycle 0: the solver did not converge")


def test_cli_an_unconverged_last_cycle_is_not_reached(tmp_path, monkeypatch, capsys):
    """Solves that do not converge (SSN held to 3 iterations): exit 1, "reached": false, the
    reason in "stopped", even where the unconverged estimate is below the accuracy (set so
    here). Before, the loop refined on by unconverged estimates until one fell below the
    accuracy and exited 0, "reached": true; "reached" without its "converged" (the mutation)
    exits 0."""
    real = adaptive.adapt

    def capped(*args, **kw):
        kw["solve_options"] = {**kw["solve_options"], "max_iter": 3}
        model, sol, cycles, why = real(*args, **kw)
        cycles[-1]["relative"] = 0.5  # an unconverged estimate below the accuracy
        return model, sol, cycles, why

    monkeypatch.setattr(adaptive, "adapt", capped)
    out = tmp_path / "o"
    assert main(["solve", "manufactured", "--accuracy", "0.99", "--out", str(out)]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert not s["reached"] and "did not converge" in s["stopped"]


def _hertz_cycles(monkeypatch, **options):
    """hertz's adaptive cycles to ≤ 2000 unknowns (cycles 0–2, nnz(A) 3k–6k) with the 2D
    threshold of a solve's "auto" lowered to 1000 entries, so that "auto" there takes amg; and
    what a solve's own "auto" runs on cycle 0's model."""
    import problems.pipeline as pipeline
    import vi_core
    from vi_core import linear_solvers

    monkeypatch.setitem(linear_solvers.AUTO_AMG_NNZ, 2, 1000)
    loaded = pipeline.load("hertz")
    model, _, cycles, _ = adaptive.adapt(
        loaded.plugin,
        loaded.scene,
        1e-6,
        max_unknowns=2000,
        solve_options={**OPTIONS, **options},
    )
    first = loaded.plugin.build(loaded.scene, 0)
    solo = vi_core.solve(first.vi, "ssn", tol=1e-10).info["linear_solver"]
    return model, cycles, solo


def test_adaptive_cycles_take_the_direct_path(monkeypatch):
    """The adaptive loop's "auto" is the direct backend on every cycle, also where a solve's
    "auto" takes amg (nnz(A) over AUTO_AMG_NNZ): on the loop's locally refined meshes SuperLU
    was 1.3–7× faster (docs/benchmarks.md, "The adaptive loop's linear solver")."""
    from vi_core.linalg import resolve_backend

    model, cycles, solo = _hertz_cycles(monkeypatch)
    assert solo == "amg"  # the rule decides here: a solve's own "auto" would take amg
    assert len(cycles) == 3 and model.vi.A.nnz > 1000
    assert [c["linear_solver"] for c in cycles] == [resolve_backend("auto", model.vi.n)] * 3


def test_cycle_linear_solver():
    """ "auto": the direct backend at every size; another name: itself."""
    from vi_core.linalg import resolve_backend

    for n in (100, 10 * adaptive.MAX_UNKNOWNS):
        assert adaptive.cycle_linear_solver("auto", n) == resolve_backend("auto", n)
    for name in ("amg", "splu"):
        assert adaptive.cycle_linear_solver(name, 100) == name


def test_adaptive_cycles_keep_a_linear_solver_asked(monkeypatch):
    """linear_solver="amg" asked is what every cycle runs."""
    _, cycles, _ = _hertz_cycles(monkeypatch, linear_solver="amg")
    assert [c["linear_solver"] for c in cycles] == ["amg"] * 3


@pytest.mark.parametrize("asked", [[], ["--linear-solver", "amg"]])
def test_cli_linear_solver_reaches_the_loop(tmp_path, monkeypatch, asked):
    """`mixvi solve --accuracy X --linear-solver S` passes S on to the loop (auto without it)."""
    seen = _loop_arguments(tmp_path, monkeypatch, asked)
    assert seen["solve_options"]["linear_solver"] == (asked[-1] if asked else "auto")


def test_mutation_auto_passed_on_takes_amg(monkeypatch):
    """Mutation: with the loop passing "auto" on to each solve (the old behaviour), the same
    cycles run amg, which test_adaptive_cycles_take_the_direct_path refuses."""
    monkeypatch.setattr(adaptive, "cycle_linear_solver", lambda asked, *_: asked)
    _, cycles, _ = _hertz_cycles(monkeypatch)
    assert [c["linear_solver"] for c in cycles] == ["amg"] * 3
