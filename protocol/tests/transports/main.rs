//! The transports against real resources, in one test binary (one link instead of two): iceoryx2
//! services (`iox`) and Unix-domain sockets (`uds`).

mod iox;
mod uds;
