//! Where the bytes of a navigator are: `size_of` of every member of
//! `DelayCompensatedNav<f32, 530>` (1 kHz IMU, 0.5 s maximum delay: the
//! configuration of issue 12's limits), each bounded so that a regression
//! shows, printed for docs/PERFORMANCE.md:
//! `cargo test --lib nav::memory -- --nocapture`.

use super::{DelayCompensatedNav, DelayCompensatedNavConfig};
use core::mem::size_of_val;

/// The history at 1 kHz for 0.5 s, as `benches/cortex-m4` sizes it.
const HIST: usize = 530;

#[test]
fn size_of_every_member_at_half_a_second() {
    let mut config = DelayCompensatedNavConfig::<f32>::default();
    config.delay_loop.fusion.delay_max_s = 0.5;
    let nav = Box::new(DelayCompensatedNav::<f32, HIST>::new(config).unwrap());
    let members = [
        (
            "forward (output predictor)",
            size_of_val(&nav.forward),
            2_200,
        ),
        ("delay_loop", size_of_val(&nav.delay_loop), 7_800),
        (
            "history (and its header cache)",
            size_of_val(&nav.history) + size_of_val(&nav.history_headers),
            8_500,
        ),
        ("times", size_of_val(&nav.times), 1_450),
        ("mags", size_of_val(&nav.mags), 800),
        // +48 B for the magnetometer modes, +48 B for the integrity configuration and monitor and
        // the IMU jump candidate (2,080 -> 2,176 B); +48 B for the GPS position-against-velocity
        // check (2,232 B); +24 B for the GPS latency allowance and its monitor (standalone
        // `Ekf16`'s levels); +8 B for the covariance repairs' counter; +16 B for the latency
        // monitor's lagged horizontal acceleration and its change's peak (the tilt share); +8 B
        // for the field offset beyond which the magnetometer is not fused; +16 B for the
        // heading's remembered tilt share and the GPS velocity innovations' mean.
        ("ekf", size_of_val(&nav.ekf), 2_352),
        // +16 B for the magnetometer options (the EKF configuration inside), +8 B for the delay
        // loop configuration's GPS rate and whether the loop follows it, +28 B for the integrity
        // risk and alert limits.
        ("config", size_of_val(&nav.config), 460),
        ("last_update", size_of_val(&nav.last_update), 400),
        (
            "whitening (accelerometer, gyroscope)",
            size_of_val(&nav.accel_whitening) + size_of_val(&nav.gyro_whitening),
            600,
        ),
        ("deltas", size_of_val(&nav.deltas), 200),
        (
            "yaw_gsf (the yaw estimator and its step)",
            size_of_val(&nav.yaw_gsf) + size_of_val(&nav.gsf_step),
            224,
        ),
    ];
    let total = size_of_val(&*nav);
    let listed: usize = members.iter().map(|m| m.1).sum();
    for (name, bytes, bound) in members {
        println!("{name}: {bytes} B");
        assert!(bytes <= bound, "{name}: {bytes} B > {bound} B");
    }
    let correlator = size_of::<crate::delay::SlidingCorrelator<f32, 125, 31, 192>>();
    println!("  of which the delay loop's SlidingCorrelator<f32, 125, 31, 192>: {correlator} B");
    assert!(correlator <= 5_600);
    println!("other members: {} B", total - listed);
    println!("DelayCompensatedNav<f32, {HIST}>: {total} B");
    assert!(total - listed <= 600);
    // +64 B for the magnetometer modes and options (the EKF +48, the configuration +16), +224 B
    // for the yaw estimator (232 B on the Cortex-M4, where `benches/cortex-m4` holds the limit of
    // 24,576 B), +80 B for the integrity configuration (twice: the navigator's and its horizon
    // filter's), the innovation monitor and the IMU jump candidate: 24,400 before them; +48 B for
    // the GPS position-against-velocity check (the Cortex-M4: 24,392); +32 B for the delay loop's
    // bias watch and its out-of-range share (the Cortex-M4: 24,416); +32 B for the horizon
    // filter's GPS latency allowance and its monitor (standalone `Ekf16`'s levels); +8 B for the
    // covariance repairs' counter; +8 B for the end of the newest IMU gap (the present's levels
    // until the horizon crosses it); +48 B for the magnetometer monitor (two body directions, the
    // learned norm and its count, the norm residual, the offset, the NIS mean) and its counter;
    // -8 B: one output entry fewer (39) for the early entries' triggers and counters; +8 B of
    // padding once the three are merged; +16 B for the latency monitor's tilt share (the
    // Cortex-M4: 24,536); +8 B for the delay's bias watch span, +8 B for the magnetometer's
    // refusal limit (the Cortex-M4: 24,552); +16 B for the heading's remembered tilt share and
    // the GPS velocity innovations' mean (the Cortex-M4: 24,568); +8 B for the delay loop's
    // sustained-motion counters, 3 B in padding on the Cortex-M4 (24,568 there).
    assert!(total <= 24_992, "{total} B");
}
