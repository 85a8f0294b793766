"""Resource bounds: unknowns and peak memory of a refinement level, known before it is built.

Unknowns. A level refines every cell into 2^d (d = the geometry's dimension: the model's
optional `dimension`, 2 if absent), so with s = 2^level the number of unknowns is a polynomial
of degree d in s (cells ~ s^d, boundary and contact nodes ~ s^(d-1), corners ~ 1). It is
fitted exactly through the levels 0 … d; in 2D a level multiplies the unknowns by about 4,
in 3D by 8. Level 0 is built (its model tells d), and the levels 1 … d too, unless the
plug-in declares `count(scene, levels) -> [(unknowns, nnz(A), n), …]` (and DIMENSION),
which counts them on the level-0 meshes (3D contact: `fem.refined_counts`, exact formulas of
uniform refinement in the coarse mesh's vertices, edges, faces and cells and the parts holding
them; nothing is assembled and nothing finer than level 0 meshed: meshing level 3 to count it
took 26 s of CPU for a level-0 block of 16 × 8 × 8 hexahedra, docs/benchmarks.md).

Peak memory. peak ≈ base + a · x^b per linear solver (MEMORY_MODEL), where x is whichever
quantity predicts that solver's measured peaks better. SuperLU: x = nnz(A), the stored entries
of the matrix Newton factorises (like the unknowns, a polynomial of degree d in 2^level); on
the unknowns instead the peaks scatter more (a scalar obstacle problem needs 2.4 kB per
unknown, the piezoelectric scenes 5–14 kB). Refitted after the memory changes (one factor alive,
minimum-degree ordering, chunked assembly) on 9 runs of 6 shipped scenes, 25k … 386k
unknowns: with b fixed at 1 (a free fit gives b = 0.89, which would extrapolate sublinearly
while the factor's fill grows faster than N), a = 245.4 bytes per stored entry, within
×0.71 … ×1.20 of the measurements. PARDISO: x = the unknowns n + m (within ×0.54 … ×1.73),
measured before those changes and not refitted (the changes only removed copies, so it
over- rather than underestimates). AMG (`--linear-solver amg`): x = nnz(A), b = 1, a = 64.77
bytes per stored entry, fitted (least squares, base fixed) to the 16 peaks AMG_MEASURED (VmHWM
of one child per run, `python benchmarks/user_mesh_solvers.py SCENES --levels L,... --solvers
amg`): the user-like gmsh meshes actuator_tri, actuator_quad, punch_graded and
cylinder_on_block at levels 2 and 3, rigid_foundation and paper_two_body at levels 2–5
(punch_graded 3 from the earlier run of docs/benchmarks.md: it timed out under load in this
one), 39k … 8.9M stored entries, 133 … 612 MiB: estimate / measured 0.796 … 1.076. Its upper
estimate (estimate / WORST_RATIO["amg"] = 0.72) exceeds every one of them by AMG_MARGIN = 10 %
at least (×1.10 … ×1.50): `mixvi solve` writes its results too and peaked 7 % above the
benchmark's child on cylinder_on_block 3 (docs/benchmarks.md). Before: a = 60.8, fitted on
paper_two_body alone at 7b9e7e2 (142, 164, 255, 619 MiB), WORST_RATIO 0.82, which the
user-like meshes exceeded by up to 7 %; a = 68.9 (the Newton matrix an operator,
`condensed_newton.CondensedNewton`, the equilibrated A on A's indices, the hierarchies built by
`amg.smoothed_aggregation`, the bodies' A and the Gram matrix X not held; peaks 141, 170,
273, 688 MB), a = 128.3 (peaks 146, 199, 400, 1191 MB and 4328 MB at level 6), before that
a = 151 and 179. It has its own model so that the guard neither refuses an AMG run by the direct
solver's larger peak nor lets one through by it.
Peaks: RSS of `mixvi solve SCENE --level L` in a fresh process (`/usr/bin/time -f %M`); `mixvi
bench` prints its measured peak beside the estimate.
Re-measure them here when the memory per unknown changes.

In 3D (the model's `dimension` 3) the fill of a sparse factor grows faster: MEMORY_MODEL_3D,
fitted on 3D runs (below), b ≈ 1.26 instead of ≈ 1. AMG: b = 1, a = 69.0 bytes per stored
entry of A, fitted (least squares, base fixed, as in 2D) to the peaks AMG_MEASURED_3D of
`mixvi bench --scenes bracket3d --levels 1..3 --linear-solvers amg` and `mixvi bench --scenes
bracket3d --levels 4..4 --linear-solvers amg --timeout 3000 --force` on the code of f65d5e5
(commit 21433f5), each case's own peak (VmHWM, `peak_rss`): levels 1–4, 7,818 … 2,509,317
unknowns, nnz(A) 236,367, 1,757,043, 13,511,079 and 105,889,887: 155, 260, 1,004 and 7,079
MiB, estimated 125, 225, 999 and 7,078 MiB (×0.81, ×0.87, ×1.00, ×1.00). The base is 2D's
115 MB and a 3D case starts higher, so the small levels are underestimated: WORST_RATIO_3D is
level 1's 0.808 rounded down, and the upper estimates of large levels are 1.25 times their
estimates. (`python -m problems.commands.main bench` reads 33–42 MiB more per case, 197, 293,
1,037 and 7,112 MiB: each spawned child re-imports that module, and the command line's imports
with it, as its `__mp_main__`.) Before, bench read ru_maxrss, which a spawned child inherits
from its parent (levels 1 and 2 read the parent's 438 MiB): a = 82.0 at 16dcc5f (levels 2 and
3, 438 and 1,142 MiB, WORST_RATIO_3D 0.56), a = 158.8 at 953d3ac, before the 3D assembly came
to work in chunks of cells (level 3: 2,148 MiB), a = 161.3 before GMRES held one vector per
iteration. The assembly computed every
cell's local matrix at once, 3,456 B per tetrahedron for the elasticity matrix, and that, not
the AMG solve, was the 3D peak (a per-phase RSS trace of bench's case at level 2, outside the
shipped commands: 406 MiB, the AMG set-up 246 MiB; chunked: 260 MiB). bracket3d level 4 measured
16,418 MiB at 56b0cc4, before both changes.

Caps. A level whose upper estimate (the estimate divided by the smallest estimate / measured
ratio seen for that solver, WORST_RATIO) exceeds the machine's memory (physical, cgroup or
RLIMIT_AS) is above the scene's cap; a level whose upper estimate exceeds the memory available
now is refused. Both are SceneErrors naming the option and printing the estimate (exit 2);
`--force` skips them. The ranks of `mixvi solve --engine petsc` each build the level: those
that share a host are refused together when the sum of their upper estimates exceeds the host's
memory available now (`check_host`; ranks on other hosts are not counted).
"""

from __future__ import annotations

import resource
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from problems.errors import SceneError
from problems.scene.geometry import check_sizes
from vi_core.linalg import pardiso_available, resolve_backend
from vi_core.linear_solvers import auto_linear_solver

from .options import MAX_LEVEL

# peak RSS [bytes] ≈ base + a · x^b per linear solver, x = nnz(A) or the unknowns n + m
# (whichever predicts that solver's measured peaks better; see the module docstring)
MEMORY_MODEL = {  # linear solver → (predictor, base [bytes], a, b)
    "splu": ("nnz", 115e6, 245.4, 1.0),
    "pardiso": ("unknowns", 175e6, 5851.0, 1.0481),
    "amg": ("nnz", 115e6, 64.77, 1.0),
}
# the AMG fit's data: (nnz(A), peak bytes) (the module docstring; the child's VmHWM in
# MiB · 2^20, benchmarks/user_mesh_solvers.py --solvers amg, at 0d41851)
AMG_MEASURED = (
    (352_508, 162.62 * 2**20),  # actuator_tri 2
    (1_422_051, 240.95 * 2**20),  # actuator_tri 3
    (544_619, 171.20 * 2**20),  # actuator_quad 2
    (2_199_947, 275.64 * 2**20),  # actuator_quad 3
    (532_730, 179.08 * 2**20),  # punch_graded 2
    (2_126_246, 297.00 * 2**20),  # punch_graded 3 (the earlier run, docs/benchmarks.md)
    (451_987, 172.95 * 2**20),  # cylinder_on_block 2
    (1_808_124, 271.46 * 2**20),  # cylinder_on_block 3
    (39_015, 134.32 * 2**20),  # rigid_foundation 2
    (160_450, 145.70 * 2**20),  # rigid_foundation 3
    (651_412, 166.50 * 2**20),  # rigid_foundation 4
    (2_614_433, 258.34 * 2**20),  # rigid_foundation 5
    (135_538, 144.69 * 2**20),  # paper_two_body 2
    (549_906, 165.54 * 2**20),  # paper_two_body 3
    (2_214_964, 255.06 * 2**20),  # paper_two_body 4
    (8_890_526, 612.03 * 2**20),  # paper_two_body 5
)
# what the AMG upper estimate must exceed every measured peak by (per dimension): 2D 10 %,
# since `mixvi solve` (results written) peaked 7 % above the benchmark's child; 3D none yet
# (its WORST_RATIO_3D is the smallest ratio itself, not re-measured against `mixvi solve`)
AMG_MARGIN = {2: 0.10, 3: 0.0}
# the smallest estimate / measured peak seen per solver (AMG: over 1 + AMG_MARGIN), rounded
# down: refusals and caps use the estimate divided by it (the most a level can need as far
# as the measurements go)
WORST_RATIO = {"splu": 0.71, "pardiso": 0.54, "amg": 0.72}
# 3D (contact scenes in 3D): a sparse factor of a 3D mesh fills far more (nested dissection:
# memory ~ n^(4/3) against n log n in 2D), so the 2D fit would underestimate a 3D level about
# 3.6× (block3d level 3: 0.93 GB estimated, 3.33 GB measured). PARDISO fitted through block3d
# levels 2 and 3 (10,115 and 72,963 unknowns: 437 MB and 3.33 GB, `/usr/bin/time -f %M mixvi
# solve block3d --level L`): b = 1.259 on the unknowns. SuperLU: one point (level 2, nnz(A) =
# 845,152: 389 MB) with PARDISO's exponent on nnz(A) (level 3 with SuperLU was not run: its
# fill grows at least as fast). Two and one measurements only: the margin is an assumed 0.5.
MEMORY_MODEL_3D = {
    "splu": ("nnz", 115e6, 9.506, 1.2585),
    "pardiso": ("unknowns", 175e6, 2388.2, 1.2585),
    # no factor: x = nnz(A), b = 1 as in 2D, a the least-squares fit (base fixed) of
    # AMG_MEASURED_3D (module docstring): 69.0 B per stored entry. block3d level 3 with cells
    # [6, 6, 4] (hexahedra, 314,531 unknowns, nnz(A) 31,621,600): 5.04 GB measured before the
    # memory changes of the 2D refit of a = 128.3 and before the chunked 3D assembly, 2.3 GB
    # estimated now (not re-measured)
    "amg": ("nnz", 115e6, 69.0, 1.0),
}
# the 3D AMG fit's data: (nnz(A), peak bytes) of bracket3d levels 1–4 (the module docstring;
# bench's peak, VmHWM, in MiB · 2^20)
AMG_MEASURED_3D = (
    (236_367, 155.00 * 2**20),
    (1_757_043, 259.98 * 2**20),
    (13_511_079, 1003.59 * 2**20),
    (105_889_887, 7079.47 * 2**20),
)
# direct solvers: an assumed margin (two and one measurements); AMG: the smallest ratio seen,
# rounded down (0.808, level 1, module docstring)
WORST_RATIO_3D = {"splu": 0.5, "pardiso": 0.5, "amg": 0.80}


@dataclass(frozen=True)
class Estimate:
    """The size of one level of a scene before it is built."""

    scene: str
    level: int
    unknowns: int
    solver: str  # the linear solver the estimate is for ("splu" or "pardiso")
    peak_bytes: float
    dimension: int = 2

    @property
    def upper_bytes(self) -> float:
        """The most this level may need: the estimate over the worst ratio measured."""
        worst = WORST_RATIO_3D if self.dimension == 3 else WORST_RATIO
        return self.peak_bytes / worst[self.solver]


def peak_bytes(unknowns: float, nnz: float, solver: str, dimension: int = 2) -> float:
    """The modelled peak resident memory of a solve with `unknowns` unknowns whose matrix A
    has `nnz` entries, with the linear solver `solver`, on a mesh of `dimension` 2 or 3."""
    model = MEMORY_MODEL_3D if dimension == 3 else MEMORY_MODEL
    predictor, base, a, b = model[solver]
    x = float(nnz if predictor == "nnz" else unknowns)
    return base + a * x**b


def fix_mmap_threshold() -> bool:
    """glibc: serve every allocation above 128 KiB by its own mmap, returned to the system when
    freed. By default glibc raises this threshold (up to 32 MB) each time a mapped block is
    freed, after which arrays of that size come from the heap, whose freed memory stays
    resident: the peak of a solve then counts arrays long freed. Measured on `mixvi bench
    --scenes paper_two_body --levels 4..4 --linear-solvers amg` (97k unknowns): peak 515 →
    447 MB. Called by the `mixvi` entry point and by each bench child; True where it took
    effect (False off glibc)."""
    try:
        import ctypes

        return ctypes.CDLL("libc.so.6").mallopt(-3, 1 << 17) == 1  # M_MMAP_THRESHOLD
    except (OSError, AttributeError):
        return False


def peak_rss() -> float:
    """This process's peak resident memory in bytes: VmHWM of /proc/self/status (Linux), the
    high-water mark of its own address space; ru_maxrss where there is no /proc.

    Why not ru_maxrss on Linux: it survives exec, so a child that `multiprocessing` spawns
    (fork, then exec) starts from its parent's resident memory at the fork: with the parent
    holding 1 GiB, a child of 28 MiB reported 1,052 MiB (VmHWM: 28). `mixvi bench`'s parent
    counts the levels before it starts the children (3D: it meshes level 3), so its small
    cases reported the parent's peak (bracket3d levels 1 and 2: 438 MiB each)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) * 1024.0  # kB → bytes
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0  # KiB (Linux) → bytes


def gb(x: float) -> str:
    """Bytes as '1.2 GB' (decimal units, as `free -g` and the README use)."""
    return f"{x / 1e9:.1f} GB" if x >= 1e8 else f"{x / 1e6:.0f} MB"


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def host_memory() -> tuple[float, float]:
    """(total, available) bytes of this host for the processes of this cgroup: physical memory
    (MemTotal/MemAvailable), bounded by a cgroup v2 limit where set; what the ranks of an
    `mpiexec` run on one host share (`check_host`)."""
    try:
        info = dict(line.split(":", 1) for line in Path("/proc/meminfo").read_text().splitlines())
        total = int(info["MemTotal"].split()[0]) * 1024
        available = int(info["MemAvailable"].split()[0]) * 1024
    except (OSError, KeyError, ValueError):
        import os

        total = available = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    limit = _read_int("/sys/fs/cgroup/memory.max")
    if limit is not None:
        used = _read_int("/sys/fs/cgroup/memory.current") or 0
        total, available = min(total, limit), min(available, max(limit - used, 0))
    return float(total), float(available)


def memory() -> tuple[float, float]:
    """(total, available) bytes for this process: the host's (`host_memory`), bounded by
    RLIMIT_AS where set."""
    total, available = host_memory()
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        total, available = min(total, soft), min(available, soft)
    return float(total), float(available)


class Sizes:
    """Unknowns and nonzeros of every level of one scene, fitted through the levels 0 … d."""

    def __init__(self, plugin, scene, linear_solver: str = "auto"):
        self.scene = scene
        self.linear_solver = linear_solver  # as asked: auto|splu|pardiso|amg
        count = getattr(plugin, "count", None)
        dim = getattr(plugin, "DIMENSION", None) if count is not None else None
        if dim is None:  # the level-0 model tells d
            model = plugin.build(scene, 0)
            dim = int(getattr(model, "dimension", 2))
            counts = [(model.vi.n + model.vi.m, model.vi.A.nnz, model.vi.n)]
            del model
        else:  # nothing built (3D contact: levels 0 … d counted on the level-0 mesh)
            with threadpool_limits(1):  # small arrays: BLAS threads cost more than they give
                counts = [tuple(int(v) for v in c) for c in count(scene, range(dim + 1))]
        for lev in range(len(counts), dim + 1):  # levels 1 … d built where the plug-in
            model = plugin.build(scene, lev)  # cannot count them
            counts.append((model.vi.n + model.vi.m, model.vi.A.nnz, model.vi.n))
            del model
        self.dimension = dim
        s = 2.0 ** np.arange(len(counts))  # (d+1,)
        v = np.array(counts, float)  # (d+1, 3): unknowns, nnz(A), n
        self._coef = np.linalg.solve(np.vander(s, len(counts)), v)  # (d+1, 3)
        self._exact = counts

    def _at(self, level: int) -> tuple[int, int, int]:
        if level < len(self._exact):
            return self._exact[level]
        v = np.vander([2.0**level], len(self._exact))[0] @ self._coef  # (3,)
        return tuple(int(round(float(x))) for x in v)

    def unknowns(self, level: int) -> int:
        """Unknowns n + m at `level` (exact for the levels built, the polynomial above)."""
        return self._at(level)[0]

    def nonzeros(self, level: int) -> int:
        """Stored entries of A at `level` (exact for the levels built, the polynomial above)."""
        return self._at(level)[1]

    def estimate(self, level: int) -> Estimate:
        """Unknowns and peak memory of `level` with the linear solver asked for (amg, or the
        direct backend `auto`/splu/pardiso resolves to)."""
        N, nnz, n = self._at(level)
        ls = self.linear_solver
        if ls == "auto":  # the iterative path above a size (`linear_solvers.auto_linear_solver`)
            ls = auto_linear_solver(nnz, n)
        solver = "amg" if ls == "amg" else resolve_backend(ls, n)
        dim = self.dimension
        return Estimate(self.scene.name, level, N, solver, peak_bytes(N, nnz, solver, dim), dim)

    def cap(self, total: float) -> int:
        """The largest level (≤ MAX_LEVEL) whose upper estimate fits in `total` bytes (0 at
        least)."""
        cap = 0
        for lev in range(MAX_LEVEL + 1):
            if self.estimate(lev).upper_bytes > total:
                break
            cap = lev
        return cap


def describe(e: Estimate) -> str:
    """'level 5 of paper_two_body: about 386,178 unknowns, peak memory about 5.8 GB (splu)'."""
    return (
        f"level {e.level} of {e.scene}: about {e.unknowns:,} unknowns, "
        f"peak memory about {gb(e.peak_bytes)}, up to {gb(e.upper_bytes)} ({e.solver})"
    )


def check_levels(
    plugin,
    scene,
    levels: tuple[int, int],
    option: str,
    text: str,
    force: bool = False,
    linear_solver: str = "auto",
    linear_option: str = "--linear-solver",
) -> Sizes:
    """Refuse (SceneError naming `option` and its value `text`) a level range A..B outside
    0 ≤ A ≤ B ≤ the scene's cap, or whose largest level does not fit in the memory available
    now; `force` skips the memory checks (the range must still be ordered, ≤ MAX_LEVEL). A
    body whose mesh at B would exceed `geometry.MAX_NODES` nodes is refused too, before any
    level is solved (a SceneError naming its key), with or without `force`. The linear
    solver 'pardiso' without its optional package is refused naming `linear_option`."""
    if linear_solver == "pardiso" and not pardiso_available():
        raise SceneError(
            linear_option,
            "pardiso",
            "an installed linear solver: 'pardiso' needs the optional package pypardiso "
            "(pip install -e '.[fast]'); or auto, splu, amg",
        )
    a, b = levels
    total, available = memory()
    sizes = Sizes(plugin, scene, linear_solver)
    cap = MAX_LEVEL if force else sizes.cap(total)
    if not 0 <= a <= b <= cap:
        why = (
            ""
            if force or cap == MAX_LEVEL
            else f" ({describe(sizes.estimate(cap + 1))}; this machine has {gb(total)}; "
            "--force to try anyway)"
        )
        allowed = f"A..B with 0 ≤ A ≤ B ≤ {cap}" if ".." in text else f"a level from 0 to {cap}"
        raise SceneError(option, text, f"expected {allowed}{why}")
    try:  # before anything is solved (the range's coarser levels are solved first)
        check_sizes(scene.validated(plugin.SCENE_MODEL), b)
    except SceneError as err:
        raise err.in_file(scene.path) from None
    e = sizes.estimate(b)
    if not force and e.upper_bytes > available:
        raise SceneError(
            option,
            text,
            f"a level that fits in the memory available now: {describe(e)}, "
            f"{gb(available)} available (--force to try anyway)",
        )
    return sizes


def check_host(e: Estimate, uppers: list[float], available: float, option: str, text: str) -> None:
    """Refuse (SceneError naming `option` and its value `text`) the level of `e` when the
    ranks on this host need more than `available`, the host's memory available now, together:
    `uppers` holds the upper estimate of every rank on this host (this one's among them; each
    rank of `--engine petsc` builds the level), ranks on other hosts not counted. One rank:
    nothing more than `check_levels`' own check."""
    if len(uppers) < 2:
        return
    total = sum(uppers)
    if total > available:
        raise SceneError(
            option,
            text,
            f"a level that fits in the memory available now: {describe(e)} on each rank, "
            f"{len(uppers)} ranks on this host need up to {gb(total)} together, "
            f"{gb(available)} available (fewer ranks per host, or --force to try anyway)",
        )


def requested_level(level: int | None, plugin, scene) -> tuple[int, str]:
    """(the level to solve, where it came from): `level` (--level) if given, else the scene's
    own ("scene.level": `[scene] level`, else the plug-in's default; SceneError if the scene
    is not valid). Nothing is built."""
    if level is not None:
        return level, "--level"
    return scene.validated(plugin.SCENE_MODEL).scene.level, "scene.level"
