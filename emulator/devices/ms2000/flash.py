"""Layout of the controller's non-volatile memory inside the device's NvStore (MS-111, MS-112).

    {"format": 1,
     "identity": {"build": ..., "version": ..., "axes": [...]},
     "saved": {"axes": {letter: {...}}, "card": {...}, "modules": {name: {...}}},   # SS Z
     "auto": {"axes": {letter: {...}}, "card": {...}},                            # saved on change
     "physical": {letter: machine counts},   # where the stage is (it does not move while off)
     "positions": {letter: user mm} | null,  # saved at power-off unless SP X=1
     "pending_factory": false}               # SS X

Axis entries are keyed by the profile's axis letters. A store whose identity differs from the
profile is ignored (and error code 55 logged by the controller).
"""

from __future__ import annotations

from typing import Any

from emulator.nvstore import NvStore

FORMAT = 1


class Flash:
    def __init__(self, store: NvStore, identity: dict[str, Any]) -> None:
        self.store = store
        self.identity = identity
        self.data: dict[str, Any] = {}

    def load(self) -> bool:
        """Read the store; False (and an empty flash) when it belongs to another identity."""
        data = self.store.load()
        if data and (data.get("format") != FORMAT or data.get("identity") != self.identity):
            self.data = {}
            return False
        self.data = data
        return True

    def _commit(self) -> None:
        self.data["format"] = FORMAT
        self.data["identity"] = self.identity
        self.store.save(self.data)

    def section(self, name: str) -> dict[str, Any] | None:
        value = self.data.get(name)
        return value if isinstance(value, dict) else None

    def write(self, **sections: Any) -> None:
        self.data.update(sections)
        self._commit()

    @property
    def pending_factory(self) -> bool:
        return bool(self.data.get("pending_factory"))
