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

from collections.abc import Callable
from typing import Any

from emulator.nvstore import NvStore, StorageError

FORMAT = 1


class Flash:
    """The layout above on top of a store. Every store operation's outcome goes to `on_result`
    (None after a successful save, the StorageError of a failed one), so the controller can flag
    it; the controller itself carries on from the in-memory copy either way."""

    def __init__(
        self, store: NvStore, identity: dict[str, Any], on_result: Callable[[StorageError | None], None]
    ) -> None:
        self.store = store
        self.identity = identity
        self.on_result = on_result
        self.data: dict[str, Any] = {}
        #: stored keys already reported as unusable since the last load (one warning per key per load)
        self.reported: set[str] = set()

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

    def _commit(self) -> None:
        self.data["format"] = FORMAT
        self.data["identity"] = self.identity
        try:
            self.store.save(self.data)
        except StorageError as failure:
            self.on_result(failure)
        else:
            self.on_result(None)

    def write(self, **sections: Any) -> None:
        self.data.update(sections)
        self._commit()

    def erase(self) -> None:
        """Factory-fresh flash; raises StorageError (flash unchanged) when the store cannot."""
        try:
            self.store.erase()
        except StorageError as failure:
            self.on_result(failure)
            raise
        self.data = {}

    @property
    def pending_factory(self) -> bool:
        return bool(self.data.get("pending_factory"))
