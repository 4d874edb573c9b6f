//! The push API of `nav_fixed` (f32 and f64, chosen by the first byte) under
//! operations decoded from the input: [machine] has the layout and the
//! checks.
#![no_main]

#[macro_use]
mod machine;

estimator_target!(
    "nav_fixed",
    delaynav::nav::DelayCompensatedNav<f32>,
    machine::push_api::f32_::nav_fixed,
    delaynav::nav::DelayCompensatedNav<f64>,
    machine::push_api::f64_::nav_fixed
);
