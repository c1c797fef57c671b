//! The live terminal view of a run (`uavloc launch` on a terminal, `uavloc simulate --live`): the map
//! with the UAV tracks, the true emitter when known, the estimate with its 95 % ellipse and the standoff
//! circle; beside it the RMSE and PCRLB over the steps, the processes (restarts, rejected messages, the
//! last hop latencies) and the planner in charge. `q` stops the run.
//!
//! - [`state`]: what the view shows, as plain data, fed by step records or the monitor's log events;
//! - [`view`]: draws that state into a ratatui frame (a pure function, tested on ratatui's test
//!   backend);
//! - [`tail`]: follows the monitor's log as it grows;
//! - [`terminal`]: the terminal itself (alternate screen, raw mode, the `q` key), restored on drop.

pub mod state;
pub mod tail;
pub mod terminal;
pub mod view;

pub use state::{LiveState, ProcessRow};
pub use tail::LogTail;
pub use terminal::LiveTerminal;
