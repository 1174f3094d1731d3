"""pyserial URL handlers of stage-emu: `stageemu://PROFILE?...` runs a device model in-process.

pyserial finds a handler for `scheme://` by importing `<package>.protocol_<scheme>` from each package
listed in `serial.protocol_handler_packages`. Importing this package adds itself to that list (once),
so after `import emulator.urlhandler` any `serial.serial_for_url("stageemu://ms2000")` works, also in
code that never mentions stage-emu. (`stage-emu` would be a valid URL scheme too, but its module,
`protocol_stage-emu`, could not be imported by name, so the scheme is `stageemu`.)
"""

from __future__ import annotations

import serial

if __name__ not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(__name__)
