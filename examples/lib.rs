//! This package holds runnable examples and nothing else: `board_loop`, `export_and_load`,
//! `eval` and `int8_drift`, each run by `cargo run --release -p cartpole-examples --example
//! NAME`.
