"""Conformance suite of the ASI MS-2000: the test vectors of the behaviour reference (§10) run
through the port with pyserial: the base controller, the low-level binary mode, TTL (§6.7) and every
firmware module. Each vector is tested here and only here (tests/unit/ms2000 keeps what the port and
the control channel do not show: the model's internals, parsers, fuzzing). By default the emulator
runs in this process in virtual time, so long moves and waits cost no wall time and timing checks
are exact; `--target daemon` runs the same tests on a daemon's pseudo-terminals in real time. Against
a real controller (`pytest tests/conformance --port /dev/ttyUSB0 --device ms2000`, plus
`--aux-port PATH` for TTL REPORT's auxiliary port) the vectors that need the control channel, exact
timing, another profile or a knob are skipped. `-m smoke` selects a fixed sample (framing, pacing,
character timing, errors, one control-channel use per file) short enough to run in real time.

Covered: TV-1…TV-218 and TV-220, each on the profile its vector names (TV-218: python-microscope's
driver), and MS-25's reading of values with trailing characters (test_parsing.py).

Left out:
- TV-219: Micro-Manager's ASIStage adapter is a C++ plug-in of a separate application, not something
  a Python test can run.
"""
