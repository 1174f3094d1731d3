"""`stage-emu` command line."""

import click


@click.group()
def main() -> None:
    """Emulate motion controllers on pseudo-terminals."""
