//! The grids of emulated boards ([`super::mcu_grid`]: the link exercise and Safra's ring;
//! [`super::mcu_tiles`]: tiles of cells), run as **one test** that runs every case in turn.
//!
//! Four QEMU boards fill this machine's two cores, so grids run one at a time. As eight tests
//! they waited for each other on a lock, each waiting test holding one of the test runner's
//! threads: once the runner reached them, both threads sat in the grids for minutes and nothing
//! else ran (the integration tests took ~300 s on 2 cores with ~1 core busy). As one test they
//! hold one thread, and the other runs every other test meanwhile. Same cases, same assertions:
//! every case runs even after one fails, each is reported with its time, and the test fails
//! naming every failed case. `RC2_BOARD_CASES=text` runs only the cases whose names contain it
//! (e.g. `RC2_BOARD_CASES=faulty cargo test --test integration board_grids`).

use std::panic::{catch_unwind, UnwindSafe};
use std::time::Instant;

use super::{mcu_grid, mcu_tiles};

/// A case: its path, as the name it is reported and filtered by, and the function.
macro_rules! case {
    ($module:ident :: $name:ident) => {
        (concat!(stringify!($module), "::", stringify!($name)), $module::$name as fn())
    };
}

/// Every grid case, by name, in the order they run.
const CASES: [(&str, fn()); 8] = [
    case!(mcu_grid::a_2x2_grid_of_boards_exchanges_every_frame_exactly_once),
    case!(mcu_grid::corrupted_and_dropped_bytes_between_boards_are_recovered_by_the_link),
    case!(mcu_grid::the_boards_detect_termination_never_early_with_a_slow_board),
    case!(mcu_grid::the_boards_detect_termination_over_faulty_links),
    case!(mcu_tiles::boards_load_and_light_their_tiles_as_host_sim_does),
    case!(mcu_tiles::boards_light_the_same_voxels_over_faulty_links),
    case!(mcu_tiles::a_slow_board_never_makes_the_ring_declare_early),
    case!(mcu_tiles::a_late_wire_against_the_ring_never_makes_it_declare_early),
];

/// Run the cases whose names contain `only` (all with `None`), each to its end; the names of
/// those that panicked.
fn run_cases(cases: &[(&'static str, impl Fn() + UnwindSafe + Copy)], only: Option<&str>) -> Vec<&'static str> {
    let mut failed = Vec::new();
    for &(name, case) in cases.iter().filter(|(name, _)| only.is_none_or(|o| name.contains(o))) {
        let t0 = Instant::now();
        let ok = catch_unwind(case).is_ok();
        eprintln!("board case {name}: {} in {:.1} s", if ok { "ok" } else { "FAILED" }, t0.elapsed().as_secs_f64());
        if !ok {
            failed.push(name);
        }
    }
    failed
}

#[test]
fn board_grids() {
    let only = std::env::var("RC2_BOARD_CASES").ok();
    let failed = run_cases(&CASES, only.as_deref());
    assert!(failed.is_empty(), "board grid cases failed (their output is above): {failed:?}");
}

/// The runner goes on past a failed case and names it; a filter runs only what it names.
#[test]
fn a_failed_case_is_named_and_the_others_still_run() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static RAN: AtomicUsize = AtomicUsize::new(0);
    fn fails() {
        RAN.fetch_add(1, Ordering::SeqCst);
        panic!("a case that fails");
    }
    fn passes() {
        RAN.fetch_add(1, Ordering::SeqCst);
    }
    let cases: [(&str, fn()); 3] = [("first fails", fails), ("second passes", passes), ("third fails", fails)];
    assert_eq!(run_cases(&cases, None), ["first fails", "third fails"]);
    assert_eq!(RAN.load(Ordering::SeqCst), 3);
    assert_eq!(run_cases(&cases, Some("second")), Vec::<&str>::new());
    assert_eq!(RAN.load(Ordering::SeqCst), 4);
}
