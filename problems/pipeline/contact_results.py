"""The contact results of the Python API (`Results.contact`) in the vocabulary of contact.csv
and contact.vtu: `lambda_n`, `lambda_t` (3D: and `lambda_t2`), `jump_t` (`jump_t2`), `state`.

A plug-in's `contact_state` keeps its own (older) key names, which the plots read; the API
hands users a `ContactResults` mapping of it whose keys are renamed (RENAMED) and from which the
per-node booleans that `state` replaces (RETIRED) are left out. For one release the old keys
stay readable, each read with a DeprecationWarning naming the new key.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping
from typing import Any

# old contact_state key → the contact.csv / contact.vtu column name of the same quantity
RENAMED = {
    "lam_n": "lambda_n",
    "lam_t": "lambda_t",  # 2D (and antiplane): the multiplier along τ
    "lam_t1": "lambda_t",  # 3D: along the first tangent t
    "lam_t2": "lambda_t2",  # 3D: along t2
    "jump_t1": "jump_t",
    "lam_t_vec": "lambda_t_vec",  # 3D: the tangential multiplier as a Cartesian vector
}
# old per-node booleans that `state` holds: still readable, with this advice
RETIRED = {
    "slip": "state == 'slip'",
    "touch": "state != 'open' (normal_state == 'touch' in 2D)",
    "touch_t": "state != 'open'",
}
REMOVAL = "the next release"


class ContactResults(Mapping):
    """A plug-in's contact state under the csv/vtu names (module docstring); `raw` the
    plug-in's own dict."""

    def __init__(self, raw: Mapping[str, Any]) -> None:
        self.raw = dict(raw)
        self._data = {RENAMED.get(k, k): v for k, v in raw.items() if k not in RETIRED}

    def __getitem__(self, key: str) -> Any:
        if key in self._data:
            return self._data[key]
        if key in RENAMED and key in self.raw:
            new = RENAMED[key]
            self._warn(key, f"contact[{new!r}]")
            return self._data[new]
        if key in RETIRED and key in self.raw:
            self._warn(key, RETIRED[key])
            return self.raw[key]
        raise KeyError(key)

    @staticmethod
    def _warn(old: str, new: str) -> None:
        warnings.warn(
            f"Results.contact[{old!r}] is deprecated and goes in {REMOVAL}: use {new} "
            "(the names of contact.csv and contact.vtu)",
            DeprecationWarning,
            stacklevel=3,
        )

    def __contains__(self, key: object) -> bool:
        return key in self._data

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"ContactResults({sorted(self._data)})"
