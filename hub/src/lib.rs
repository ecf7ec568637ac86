//! The communication hub: decision gate, ATT, ordered delivery and the hub role.
