//! The interpreter's tests: exact replies per command (`commands`), and
//! randomized streams (`randomized`), both against the test double of the
//! mount (`double`).

mod commands;
mod double;
mod randomized;
