"""The one error a user sees for bad input: which file, which key, which value, what is allowed."""

from __future__ import annotations

from typing import Any


class SceneError(Exception):
    """Bad input in a scene; the command line prints `str(err)` and exits with status 2."""

    def __init__(self, key: str, value: Any, allowed: str, file: str | None = None):
        self.key, self.value, self.allowed, self.file = key, value, allowed, file
        super().__init__(self._message())

    def _message(self) -> str:
        where = f"{self.file}: " if self.file else ""
        shown = repr(self.value)
        if len(shown) > 80:  # both ends kept: a long path's file name is at its end
            shown = shown[:37] + "..." + shown[-40:]
        return f"{where}{self.key} = {shown}: {self.allowed}"

    def in_file(self, file: str) -> SceneError:
        """The same error, attributed to `file`."""
        return SceneError(self.key, self.value, self.allowed, file)
