//! The usage examples in `examples/` run as part of the test suite (the same code, not a copy).
#[path = "../examples/incision.rs"]
mod incision;

#[test]
fn incision_example_runs() {
    incision::main().unwrap();
}
