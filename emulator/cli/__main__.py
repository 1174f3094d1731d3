"""`python -m emulator.cli`: the `stage-emu` command."""

from emulator.cli import main

if __name__ == "__main__":
    main()
