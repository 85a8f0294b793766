"""ParaView collections (`.pvd`): one file that opens a series of VTK datasets as time steps.

    write_pvd(path, [(time_or_index, relative_file), ...])

is the one writer every command uses: `mixvi solve` for the levels of a nested solve (time =
level), `mixvi study --vtu` for its cases (time = level, one collection per solver), and a load
path for its load steps (time = the load parameter or the step index). Datasets that share a
time are the parts of that step (a body each, the contact line), numbered in the order given,
so ParaView shows them together and steps through the times with its time controls.

Files are named relative to the folder of the `.pvd` (the collection moves with its folder);
times must be finite numbers. The writer only writes the XML: whether the named files exist is
the caller's business (a folder is committed as a whole by `problems.output.files`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path, PurePosixPath
from xml.sax.saxutils import quoteattr


def pvd_text(datasets: Sequence[tuple[float, str]]) -> str:
    """The XML of a collection of `datasets`, (time, file relative to the .pvd) each.

    ValueError for a time that is not a finite number or a file name that is absolute, empty
    or climbs out of the collection's folder ('..')."""
    rows, parts = [], {}
    for t, f in datasets:
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
            raise ValueError(f"pvd dataset {f!r}: time {t!r} is not a finite number")
        name = PurePosixPath(str(f).replace("\\", "/"))
        if not str(f) or name.is_absolute() or ".." in name.parts:
            raise ValueError(
                f"pvd dataset {f!r}: a file name relative to the .pvd's folder, inside it"
            )
        part = parts.get(float(t), 0)
        parts[float(t)] = part + 1
        rows.append(
            f"    <DataSet timestep={quoteattr(repr(float(t)))} part={quoteattr(str(part))} "
            f"file={quoteattr(str(name))}/>"
        )
    body = "\n".join(rows)
    return (
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n'
        + (body + "\n" if body else "")
        + "  </Collection>\n</VTKFile>\n"
    )


def vtu_datasets(time: float, files: Sequence[str]) -> list[tuple[float, str]]:
    """The `.vtu` files among `files` as datasets of one time step, the bodies before the
    contact line (`contact.vtu`), for `write_pvd`."""
    vtus = sorted(
        (f for f in files if f.endswith(".vtu")),
        key=lambda f: (PurePosixPath(f).name == "contact.vtu", f),
    )
    return [(time, f) for f in vtus]


def write_pvd(path: Path, datasets: Sequence[tuple[float, str]]) -> None:
    """Write the ParaView collection `path` of `datasets`: (time or index, file relative to
    the folder of `path`) each; datasets of one time are the parts of that step."""
    Path(path).write_text(pvd_text(datasets))
