//! The `uavloc` command-line interface.
