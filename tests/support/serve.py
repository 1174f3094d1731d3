"""`stage-emu` with the test-only probe family registered (integration tests run this as a subprocess)."""

import tests.support.probe_device  # noqa: F401  (registers the family)
from emulator.cli import main

if __name__ == "__main__":
    main()
