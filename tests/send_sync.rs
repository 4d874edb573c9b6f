//! The navigator, the filters, the delay loop, the calibrator and the
//! configurations can move to another thread and be shared by reference
//! (`Send + Sync`), in both precisions. A compile-time check: the test fails
//! to build if a field stops allowing it.

use delaynav::delay::DefaultCalibrator;
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, DefaultDelayLoop, DelayCompensatedNav,
    DelayCompensatedNavConfig, Ekf16, Ekf16Config, Error, Estimate, Scalar,
};

const fn send_sync<T: Send + Sync>() {}

const fn every_estimator<T: Scalar>() {
    send_sync::<DelayCompensatedNav<T>>();
    send_sync::<Ekf16<T>>();
    send_sync::<AugmentedEkf17<T>>();
    send_sync::<DefaultDelayLoop<T>>();
    send_sync::<DefaultCalibrator<T>>();
    send_sync::<DelayCompensatedNavConfig<T>>();
    send_sync::<Ekf16Config<T>>();
    send_sync::<AugmentedEkf17Config<T>>();
    send_sync::<Estimate<T>>();
}

const _: () = every_estimator::<f32>();
const _: () = every_estimator::<f64>();
const _: () = send_sync::<Error>();

#[test]
fn a_navigator_runs_on_another_thread() {
    let nav = DelayCompensatedNav::<f32>::new(DelayCompensatedNavConfig::default()).unwrap();
    let nav = std::thread::spawn(move || nav).join().unwrap();
    assert!(nav.delay_s() > 0.0);
}
