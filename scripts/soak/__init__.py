"""Attacks and campaigns of the torture suite (`make soak`, scripts/torture.py); short forms of
each run in `make test`."""
