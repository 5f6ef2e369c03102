//! The run's story on its figure: the events that explain it (a wait, a shape change, a
//! halt, an emergency stop, the goal), numbered in time order, pinned on the map where
//! the leader was and marked on every time plot, and listed with their times.

use base_station::station::Severity;
use plotters::prelude::*;

use super::{PlotResult, TimeChart};
use crate::report::StationEventReport;
use crate::world::World;

/// At most this many pins: beyond it a figure is a blur of numbers.
const MAX_PINS: usize = 20;
/// The same event again within this is the same story (a wait broken by a period), s.
const SAME_WITHIN_S: f64 = 3.0;

/// One event pinned.
#[derive(Debug, Clone, PartialEq)]
pub struct Pin {
    /// Its number on the figure, from 1.
    pub n: usize,
    pub at_s: f64,
    /// What happened, in words.
    pub text: String,
    pub severity: Severity,
}

/// An event's words on the figure, if it is one the story needs.
fn words(event: &str, robot: Option<u16>) -> Option<String> {
    let who = robot.map_or(String::new(), |r| format!("robot {r} "));
    let text = match event.split(':').next().unwrap_or_default() {
        "yielding" => "waits for people".to_string(),
        "stepping_back" => "steps back from someone".to_string(),
        "clearing_way" => "goes on out of someone's way".to_string(),
        "stepping_aside" => "steps out of someone's lane".to_string(),
        "formation_to_line" => "into the line".to_string(),
        e if e.starts_with("formation_to_") => "back to the wide shape".to_string(),
        "leader_lost" => "leader lost: the fleet stops".to_string(),
        "leader_back" => "leader heard again".to_string(),
        "robot_fault" => format!("{who}fault: {}", event.split(':').nth(1).unwrap_or("?")),
        "localization_lost" => "localization lost".to_string(),
        "no_route" => "no route".to_string(),
        "operator_stop" => "operator: Stop".to_string(),
        "operator_emergency_stop" => "operator: EMERGENCY STOP".to_string(),
        "operator_resume" => "operator: Resume".to_string(),
        "follower_behind" => format!("{who}left behind"),
        "goal_reached" => "goal reached".to_string(),
        _ => return None,
    };
    Some(text.replace('_', " "))
}

/// The events of a report worth a pin, numbered, the same one again soon after merged.
pub fn pins(events: &[StationEventReport]) -> Vec<Pin> {
    let mut out: Vec<Pin> = Vec::new();
    let mut last: Vec<(String, f64)> = Vec::new();
    for e in events {
        let Some(text) = words(&e.event, e.robot) else {
            continue;
        };
        let again = last
            .iter()
            .any(|(t, at)| *t == text && e.at_s - at < SAME_WITHIN_S);
        last.retain(|(t, _)| *t != text);
        last.push((text.clone(), e.at_s));
        if again || out.len() >= MAX_PINS {
            continue;
        }
        out.push(Pin {
            n: out.len() + 1,
            at_s: e.at_s,
            text,
            severity: Severity::of(&e.event),
        });
    }
    out
}

fn ink(severity: Severity) -> RGBColor {
    match severity {
        Severity::Error => RGBColor(200, 0, 0),
        Severity::Warning => RGBColor(170, 90, 0),
        Severity::Info => RGBColor(40, 40, 40),
    }
}

/// A numbered disc at `at` (plot coordinates).
fn badge<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    at: (f64, f64),
    pin: &Pin,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let colour = ink(pin.severity);
    let label = pin.n.to_string();
    let style = ("sans-serif", 11).into_font().color(&WHITE);
    let dx = if pin.n >= 10 { -6 } else { -3 };
    chart.draw_series(std::iter::once(
        EmptyElement::at(at)
            + Circle::new((0, 0), 8, colour.filled())
            + Text::new(label, (dx, -5), style),
    ))?;
    Ok(())
}

/// Each pin on the map, where the leader was at its time.
pub fn on_map<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
    pins: &[Pin],
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let Some(leader) = world
        .robots
        .iter()
        .position(|r| r.role == base_station::scenario::Role::Leader)
    else {
        return Ok(());
    };
    for pin in pins {
        if let Some(s) = super::sample_at(world, pin.at_s) {
            let r = &s.robots[leader];
            badge(chart, (r.x, r.y), pin)?;
        }
    }
    Ok(())
}

/// Each pin on a time plot: a dashed line at its time, its number at the top.
pub fn on_time<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    pins: &[Pin],
    y: std::ops::Range<f64>,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    for pin in pins {
        let colour = ink(pin.severity).mix(0.6);
        chart.draw_series(DashedLineSeries::new(
            [(pin.at_s, y.start), (pin.at_s, y.end)],
            3,
            3,
            colour.stroke_width(1),
        ))?;
        let top = y.end - 0.04 * (y.end - y.start);
        badge(chart, (pin.at_s, top), pin)?;
    }
    Ok(())
}

/// The pins' list, in the map panel's lower left corner.
pub fn list<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    pins: &[Pin],
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    if pins.is_empty() {
        return Ok(());
    }
    let (_, h) = area.dim_in_pixel();
    let line = 15;
    let top = h as i32 - 50 - line * pins.len() as i32;
    let width = 12 + 7 * pins.iter().map(|p| p.text.len() + 12).max().unwrap_or(0) as i32;
    let height = line * pins.len() as i32 + 8;
    area.draw(&Rectangle::new(
        [(60, top - 4), (60 + width, top + height)],
        WHITE.mix(0.85).filled(),
    ))?;
    area.draw(&Rectangle::new(
        [(60, top - 4), (60 + width, top + height)],
        BLACK.stroke_width(1),
    ))?;
    for (i, pin) in pins.iter().enumerate() {
        let style = ("sans-serif", 12).into_font().color(&ink(pin.severity));
        let text = format!("{:>2}  {:>6.1} s  {}", pin.n, pin.at_s, pin.text);
        area.draw(&Text::new(text, (68, top + line * i as i32), style))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wait_broken_by_a_period_is_one_pin_and_the_rest_are_left_out() {
        let e = |at_s: f64, event: &str| StationEventReport {
            at_s,
            event: event.to_string(),
            robot: None,
        };
        let events = vec![
            e(1.0, "linked"),
            e(10.0, "yielding"),
            e(11.0, "yielding"),
            e(20.0, "formation_to_line"),
            e(30.0, "robot_fault:wheel_stall_left:fleet_halted"),
        ];
        let p = pins(&events);
        let texts: Vec<&str> = p.iter().map(|p| p.text.as_str()).collect();
        assert_eq!(
            texts,
            [
                "waits for people",
                "into the line",
                "fault: wheel stall left"
            ]
        );
        assert_eq!(p[2].severity, Severity::Error);
        assert_eq!(p.iter().map(|p| p.n).collect::<Vec<_>>(), [1, 2, 3]);
    }
}
