//! The push API of `ekf16` (f32 and f64, chosen by the first byte) under
//! operations decoded from the input: [machine] has the layout and the
//! checks.
#![no_main]

#[macro_use]
mod machine;

estimator_target!(
    "ekf16",
    delaynav::Ekf16<f32>,
    machine::push_api::f32_::ekf16,
    delaynav::Ekf16<f64>,
    machine::push_api::f64_::ekf16
);
