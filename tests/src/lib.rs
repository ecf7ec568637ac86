//! End-to-end tests: real role processes over real iceoryx2 services.
