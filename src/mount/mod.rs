//! The mount: its configuration and derived rates, step generation, the ST4
//! guide port's state machine, the controller that turns pulses and the
//! model's feed-forward into step rates and guide frames, and the optional
//! worm-index sensor's passes.

pub mod config;
pub mod frame;
pub mod guiding;
pub mod learner;
pub mod st4;
pub mod step_pulse;
pub mod stepgen;
pub mod worm_index;
