//! The usage examples in `examples/` run as part of the test suite (the same code, not a copy).
#[path = "../examples/sheared_box.rs"]
mod sheared_box;

#[test]
fn sheared_box_example_runs() {
    sheared_box::main().unwrap();
}
