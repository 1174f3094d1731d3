"""What the emulator keeps on disk: a device's flash and the daemon's runtime directory."""
