//! `register benchmark --quick` says it is a smoke test where it is offered (issue 50, item 7): its
//! help. (Its table header says so too; the quick run itself is tested in register_benchmark_cli.rs.)
mod common;

#[test]
fn quick_is_called_a_smoke_test_in_the_help() {
    let o = common::run(&["register", "benchmark", "--help"]);
    let h = String::from_utf8_lossy(&o.stdout);
    let quick = h.split("--quick").nth(1).unwrap_or("");
    let until_next = quick.split("\n      --").next().unwrap_or("");
    assert!(until_next.contains("smoke test") && until_next.contains("not a ranking"), "{until_next}");
}
