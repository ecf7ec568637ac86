//! Role runtime: the Role trait, the process host, and the iceoryx2 transport with flight namespaces.
