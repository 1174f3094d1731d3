"""Conformance suite of the ASI MS-2000: the test vectors of the behaviour reference (§10) run
through the port with pyserial: the base controller, the low-level binary mode, TTL (§6.7) and the
firmware modules emulated so far. Against a real controller
(`pytest tests/conformance --port /dev/ttyUSB0 --device ms2000`) the vectors that need the control
channel, exact timing, another profile or a knob are skipped.

Covered: TV-1…TV-153, TV-181…TV-184, TV-187…TV-192, TV-199…TV-204, TV-208…TV-218 (TV-218:
python-microscope's driver), and MS-25's reading of values with trailing characters
(test_parsing.py). The vectors naming `ms2000-seq` (ARRAY, DAC OUT, PLANAR CORRECTION) run on that
build without its SEQUENCER, and TV-183 (`ms2000-pz-crisp`) on its piezo Z without CRISP
(tests/support/ms2000_builds.py), until those modules exist.

Left out, for a later issue:
- TV-154…TV-156 (TTL REPORT), TV-157…TV-168 (CRISP), TV-169…TV-180 (AUTOFOCUS), TV-185, TV-186
  (DLED, the other LED driver of §9.8), TV-193…TV-198 and TV-220 (SEQUENCER), TV-205…TV-207
  (TRACKING): modules that are not emulated yet.
- TV-219: Micro-Manager's ASIStage adapter is a C++ plug-in of a separate application, not something
  a Python test can run.
"""
