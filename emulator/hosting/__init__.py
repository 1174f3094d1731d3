"""Running models on ports: the daemon, the runner, the transports, the control channel."""
