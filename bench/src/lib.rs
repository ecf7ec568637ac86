//! Benchmarks: IPC ping-pong, gate cost, controller jitter.
