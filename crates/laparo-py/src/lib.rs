//! laparo-py — the Python package `laparo` (PyO3 + maturin, one abi3 wheel): RoDEM depth
//! evaluation (thesis §3.2), CATS augmentation and stereo geometry (§3.3), Conformal
//! Perspective Correction (Ch. 4), differentiable MPM (§5.2), feature detection / matching /
//! robust two-view geometry (§4.2, §4.5), semi-global stereo matching, RODS-MPM
//! registration and its mesh baselines (Ch. 5), volume meshing and the Neo-Hookean FEM (§5.4.2) on
//! NumPy arrays.
//!
//! This crate is the compiled extension `laparo._laparo`; the Python modules in
//! `python/laparo/` wrap it with keyword arguments, docstrings and `.pyi` stubs. Every entry
//! point validates its arguments (dtype, shape, contiguity, NaN) and raises `TypeError` /
//! `ValueError` naming the argument; a Rust panic becomes a `RuntimeError`, never an abort.
//! Heavy work runs with the GIL released.
//!
//! Build: `maturin develop --release -m crates/laparo-py/Cargo.toml` (see README.md).
#![warn(missing_docs)]

mod alloc;
mod arrays;
mod baselines;
mod cpc;
mod depth;
mod features;
mod fem;
mod mpm;
mod register;
mod stereo;
mod stereo_match;

use pyo3::prelude::*;

/// The extension's allocator: the system's plus a cache of large freed buffers (see `alloc`).
#[global_allocator]
static ALLOC: alloc::CachingAlloc = alloc::CachingAlloc::new();

/// The compiled module; see the Python package `laparo` for the documented API.
#[pymodule]
fn _laparo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(arrays::set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::get_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(alloc::set_buffer_cache_mb, m)?)?;
    m.add_function(wrap_pyfunction!(depth::depth_evaluate_pair, m)?)?;
    m.add_function(wrap_pyfunction!(depth::depth_evaluate_batch, m)?)?;
    m.add_function(wrap_pyfunction!(depth::depth_perturb, m)?)?;
    m.add_function(wrap_pyfunction!(depth::depth_item_seed, m)?)?;
    m.add_function(wrap_pyfunction!(depth::depth_perturbation_kinds, m)?)?;
    m.add_class::<stereo::PyCatsConfig>()?;
    m.add_function(wrap_pyfunction!(stereo::cats_sample_params, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_augment, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_discover, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_augment_folder_sample, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_augment_sample_files, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_sample_seed, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::cats_augment_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::stereo_read_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::stereo_rectify, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::stereo_disparity_to_depth, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::stereo_depth_to_disparity, m)?)?;
    m.add_function(wrap_pyfunction!(stereo::stereo_evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(stereo_match::stereo_match, m)?)?;
    m.add_function(wrap_pyfunction!(stereo_match::stereo_self_rectify, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_detect, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_match, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_match_images, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_find_homography, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_find_fundamental, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_find_essential, m)?)?;
    m.add_function(wrap_pyfunction!(features::features_transfer_error, m)?)?;
    m.add_function(wrap_pyfunction!(register::register_run, m)?)?;
    m.add_function(wrap_pyfunction!(register::register_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(register::register_assumed_cut, m)?)?;
    m.add_function(wrap_pyfunction!(baselines::register_arap, m)?)?;
    m.add_function(wrap_pyfunction!(baselines::register_drbc, m)?)?;
    m.add_function(wrap_pyfunction!(baselines::register_lddmm, m)?)?;
    m.add_function(wrap_pyfunction!(fem::fem_tetrahedralize, m)?)?;
    m.add_function(wrap_pyfunction!(fem::fem_quality, m)?)?;
    m.add_function(wrap_pyfunction!(fem::fem_solve, m)?)?;
    m.add_function(wrap_pyfunction!(fem::fem_cut, m)?)?;
    m.add_class::<cpc::PyCpcWarp>()?;
    m.add_function(wrap_pyfunction!(cpc::cpc_warp_frame, m)?)?;
    m.add_class::<mpm::PyMpmScene>()?;
    m.add_function(wrap_pyfunction!(mpm::mpm_box_lattice, m)?)?;
    m.add_function(wrap_pyfunction!(mpm::mpm_cfl_dt, m)?)?;
    Ok(())
}
