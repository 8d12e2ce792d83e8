//! `ENGINE_BUILD_ID` (read by `engine::BUILD_ID`): the engine's and the bundle crate's sources,
//! the engine's compiled-in data and `Cargo.lock` (`build_id.rs`).

#[path = "build_id.rs"]
mod build_id;

fn main() {
    build_id::emit(
        "ENGINE_BUILD_ID",
        &[("src", true), ("../bundle/src", true), ("data", false)],
    );
}
