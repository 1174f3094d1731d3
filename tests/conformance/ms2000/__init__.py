"""Conformance suite of the ASI MS-2000: the test vectors of the behaviour reference (§10) that concern
the base controller, the low-level binary mode, TTL (§6.7), RING BUFFER (§9.2) and LED DIMMER (§9.8),
run through the port with pyserial. Against a real controller
(`pytest tests/conformance --port /dev/ttyUSB0 --device ms2000`) the vectors that need the control
channel, exact timing, another profile or a knob are skipped.

Covered: TV-1…TV-91, TV-93…TV-128, TV-139…TV-145, TV-184, TV-215 (module gating on the default
profile) and TV-218 (python-microscope's driver).

Left out, for a later issue:
- TV-92: needs the NO CHANGE SETTINGS module (`ms2000-all-modules`), not emulated; `VB T` without it
  is checked by TV-91.
- TV-129…TV-138 (ARRAY), TV-146…TV-153 (SCAN), TV-154…TV-156 (TTL REPORT), TV-157…TV-168 (CRISP),
  TV-169…TV-180 (AUTOFOCUS), TV-181…TV-183 (DAC OUT), TV-185, TV-186 (DLED, the other LED driver of
  §9.8), TV-187…TV-192 (PLANAR CORRECTION), TV-193…TV-198 and TV-220 (SEQUENCER), TV-199…TV-204
  (TRACER), TV-205…TV-207 (TRACKING), TV-208, TV-209 (MULTIAXIS MOVES), TV-210 (PEDALS), TV-211
  (XY KNOBS), TV-212…TV-214 (SEARCH INDEX / SEEK LIMITS), TV-216, TV-217 (SECURE): modules that are
  not emulated yet, and their profiles do not exist.
- TV-219: Micro-Manager's ASIStage adapter is a C++ plug-in of a separate application, not something
  a Python test can run.
"""
