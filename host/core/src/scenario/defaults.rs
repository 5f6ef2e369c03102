//! Defaults of the optional scenario fields (serde `default = …`).

pub fn distance() -> f64 {
    3.0
}
pub fn angle_deg() -> f64 {
    150.0
}
pub fn per_row() -> usize {
    3
}
pub fn line_spacing() -> f64 {
    1.5
}
pub fn margin() -> f64 {
    0.5
}
pub fn transition_s() -> f64 {
    3.5
}
pub fn min_dwell_s() -> f64 {
    2.0
}
pub fn lookahead() -> f64 {
    5.0
}
pub fn arrival_tolerance() -> f64 {
    0.3
}
pub fn waypoint_tolerance() -> f64 {
    1.0
}
