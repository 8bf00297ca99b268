//! This package holds runnable examples and nothing else: `board_loop`, `export_and_load`
//! and `eval`, each run by `cargo run --release -p cartpole-examples --example NAME`.
