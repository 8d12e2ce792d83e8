//! `SIMULATOR_BUILD_ID` (read by `simulator::BUILD_ID`): the application's sources and data,
//! and everything the engine's id covers (`../engine/build_id.rs`). Checkpoints and cluster
//! plans are keyed by it: the driver's scheduling (round ends, block order) decides the sums as
//! much as the engine's estimators do.

#[path = "../engine/build_id.rs"]
mod build_id;

fn main() {
    build_id::emit(
        "SIMULATOR_BUILD_ID",
        &[
            ("src", true),
            ("data", false),
            ("../engine/src", true),
            ("../engine/data", false),
            ("../bundle/src", true),
        ],
    );
}
