"""Layout of the controller's non-volatile memory inside the store the host hands in (MS-111, MS-112).

    {"format": 1,
     "identity": {"build": ..., "version": ..., "axes": [...]},
     "saved": {"axes": {letter: {...}}, "card": {...}, "modules": {name: {...}}},   # SS Z
     "auto": {"axes": {letter: {...}}, "card": {...}, "modules": {name: {...}}},  # saved on change
     "physical": {letter: machine counts},   # where the stage is (it does not move while off)
     "positions": {letter: user mm} | null,  # saved at power-off unless SP X=1
     "pending_factory": false}               # SS X

Axis entries are keyed by the profile's axis letters. A store whose identity differs from the
profile is ignored (and error code 55 logged by the controller).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from emulator.device import DeviceServices, Store
from emulator.storage.nvstore import StorageError

FORMAT = 1


class Flash:
    """The layout above on a store the host hands in (the model never sees a file). Every save's
    outcome goes to `on_result` (None once it is on disk, else its StorageError), so the controller
    can flag it; the controller carries on from the in-memory copy either way. `settled` is False
    while a save is still on its way to the disk (a store that writes in the background)."""

    def __init__(
        self,
        services: DeviceServices,
        device_id: str,
        identity: dict[str, Any],
        on_result: Callable[[StorageError | None], None],
    ) -> None:
        self.identity = identity
        self.on_result = on_result
        self.store: Store = services.open_store(device_id, self._settled)
        self.data: dict[str, Any] = {}
        self.settled = True
        #: stored keys already reported as unusable since the last load (one warning per key per load)
        self.reported: set[str] = set()

    @property
    def persistent(self) -> bool:
        return self.store.persistent

    def load(self) -> bool:
        """Read the store; False (and an empty flash) when it belongs to another identity."""
        self.reported = set()
        try:
            data = self.store.load()
        except StorageError as failure:
            self.on_result(failure)
            data = {}
        if data and (data.get("format") != FORMAT or data.get("identity") != self.identity):
            self.data = {}
            return False
        self.data = data
        return True

    def write(self, **sections: Any) -> None:
        """Replace whole sections (never change a saved one in place: the store keeps only a
        shallow copy of each image until its writer has encoded it)."""
        self.data.update(sections)
        self.data["format"] = FORMAT
        self.data["identity"] = self.identity
        self.settled = False
        self.store.save(self.data)

    def _settled(self, failure: StorageError | None) -> None:
        self.settled = True
        self.on_result(failure)

    def erase(self) -> None:
        """Factory-fresh flash; raises StorageError (flash unchanged) when the store cannot."""
        try:
            self.store.erase()
        except StorageError as failure:
            self.on_result(failure)
            raise
        self.data = {}
        self.settled = True

    @property
    def pending_factory(self) -> bool:
        return bool(self.data.get("pending_factory"))
