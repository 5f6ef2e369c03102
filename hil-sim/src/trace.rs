//! The run's trace: one CSV row per robot per sample (10 Hz), for pandas or a plot tool.
//!
//! Columns: `t` (s), `id`, `role`, `x`, `y` (m), `heading` (rad), `v` (m/s), `omega`
//! (rad/s), `slot_x`, `slot_y` (m, followers: the reference point), `error` (m, followers),
//! `mode` (the robot's last reported mode), `shape` (`wide`, `to_line`, `line`, `to_wide`),
//! `blend` (0 wide … 1 line). Empty cells where a value does not apply.

use std::io::Write;

use base_station::scenario::Role;
use serde::Serialize;

use crate::metrics::Recorder;

#[derive(Serialize)]
struct Row<'a> {
    t: f64,
    id: u16,
    role: &'a str,
    x: f64,
    y: f64,
    heading: f64,
    v: f64,
    omega: f64,
    slot_x: Option<f64>,
    slot_y: Option<f64>,
    error: Option<f64>,
    mode: Option<&'a str>,
    shape: &'a str,
    blend: f64,
}

/// Writes the trace of `rec`; `roles`: each robot's id and role in the samples' order.
pub fn write_csv<W: Write>(rec: &Recorder, roles: &[(u16, Role)], out: W) -> csv::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    for s in &rec.samples {
        for (r, (id, role)) in s.robots.iter().zip(roles) {
            w.serialize(Row {
                t: s.t,
                id: *id,
                role: role.name(),
                x: r.x,
                y: r.y,
                heading: r.heading,
                v: r.v,
                omega: r.omega,
                slot_x: r.slot.map(|p| p.0),
                slot_y: r.slot.map(|p| p.1),
                error: r.error,
                mode: r.mode,
                shape: s.shape,
                blend: s.blend,
            })?;
        }
    }
    w.flush()?;
    Ok(())
}
