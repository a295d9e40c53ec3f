//! The firmware's tasks: each only wires hardware (`hal`) to the library's
//! loop and model; nothing here decides how the mount moves.

pub mod fault;
pub mod guiding_task;
pub mod learning_task;
pub mod log;
pub mod port_io;
pub mod shared;
pub mod step_tick;
pub mod storage;
