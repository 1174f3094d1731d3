"""The benchmark's measurements (scripts/bench.py composes them into one table).

common: the `Result` every measurement returns, statistics, daemons, profile values, CPU placement;
floor and responder: the no-parsing PTY floor; roundtrip, throughput, timing, timescale: one module
per group of targets.
"""
