//! Supervisor: workflow files, process spawning, CPU binding, heartbeat statistics, restarts, status.
