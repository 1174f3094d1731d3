"""Offline traffic tools: trace, plot, proxy and replay, view, capture."""
