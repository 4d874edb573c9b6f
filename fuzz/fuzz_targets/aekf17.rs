//! The push API of `aekf17` (f32 and f64, chosen by the first byte) under
//! operations decoded from the input: [machine] has the layout and the
//! checks.
#![no_main]

#[macro_use]
mod machine;

estimator_target!(
    "aekf17",
    delaynav::AugmentedEkf17<f32>,
    machine::push_api::f32_::aekf17,
    delaynav::AugmentedEkf17<f64>,
    machine::push_api::f64_::aekf17
);
