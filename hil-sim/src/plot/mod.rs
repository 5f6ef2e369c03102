//! The run's figure, like the paper's: trajectories with obstacles and formation
//! snapshots; tracking error over time; linear and angular velocities over time. SVG.

use std::ops::Range;
use std::path::Path;

use base_station::geometry::Obstacle;
use base_station::scenario::Role;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use base_station::perception::tracking::Motion;
use base_station::scenario::movers::MoverShape;
use glam::DVec2;

use crate::movers::MoverState;
use crate::report::Report;
use crate::world::World;

mod pins;

const COLORS: [RGBColor; 6] = [
    RGBColor(200, 30, 30),
    RGBColor(30, 90, 200),
    RGBColor(30, 150, 60),
    RGBColor(200, 130, 0),
    RGBColor(130, 50, 170),
    RGBColor(0, 150, 150),
];

fn color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// Points around a circle, closed.
fn circle(cx: f64, cy: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=36)
        .map(|i| {
            let a = i as f64 / 36.0 * std::f64::consts::TAU;
            (cx + r * a.cos(), cy + r * a.sin())
        })
        .collect()
}

/// The series' legend, boxed, at `position`.
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    position: SeriesLabelPosition,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// A chart with two metric axes (time and a value, or x and y on the site).
type TimeChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart over the run's time with the given caption and y range.
fn time_chart<'a, DB: DrawingBackend>(
    world: &World,
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    y: std::ops::Range<f64>,
) -> Result<TimeChart<'a, DB>, Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    let t_end = world.recorder.samples.last().map_or(1.0, |s| s.t);
    Ok(ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t_end, y)?)
}

/// A site this much wider than deep is drawn across the figure's width, the time plots
/// side by side below it; a squarer one on the left, the time plots stacked on the right.
const WIDE_SITE: f64 = 1.6;

pub fn write_svg(world: &World, report: &Report, path: &Path) -> PlotResult {
    let pins = pins::pins(&report.station_events);
    let (lo, hi) = site_extent(world);
    let aspect = (hi.0 - lo.0) / (hi.1 - lo.1).max(1e-6);
    if aspect > WIDE_SITE {
        let map_h = (1480.0 / aspect + 110.0).clamp(300.0, 640.0) as u32;
        let root = SVGBackend::new(path, (1500, map_h + 380)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(map_h);
        let (left, right) = bottom.split_horizontally(750);
        trajectories(world, report, &top, &pins)?;
        errors(world, &left, &pins)?;
        velocities(world, &right, &pins)?;
        root.present()?;
    } else {
        let root = SVGBackend::new(path, (1500, 760)).into_drawing_area();
        root.fill(&WHITE)?;
        let (left, right) = root.split_horizontally(760);
        let (top, bottom) = right.split_vertically(380);
        trajectories(world, report, &left, &pins)?;
        errors(world, &top, &pins)?;
        velocities(world, &bottom, &pins)?;
        root.present()?;
    }
    Ok(())
}

/// The box (low corner, high corner) that holds the robots' paths, the obstacles and the
/// goal, with a metre around.
fn site_extent(world: &World) -> ((f64, f64), (f64, f64)) {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut grow = |x: f64, y: f64| {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    };
    for s in &world.recorder.samples {
        for r in &s.robots {
            grow(r.x, r.y);
        }
    }
    for o in world.map.obstacles() {
        let [a, b] = o.bounds();
        grow(a.x, a.y);
        grow(b.x, b.y);
    }
    if let Some(g) = world.station.guidance().planner().goal() {
        grow(g.x, g.y);
    }
    ((lo.0 - 1.0, lo.1 - 1.0), (hi.0 + 1.0, hi.1 + 1.0))
}

/// `lo..hi` grown in x or in y so that a metre is as long either way on a plot of
/// `pixels` (width, height).
fn fitted(lo: (f64, f64), hi: (f64, f64), pixels: (u32, u32)) -> (Range<f64>, Range<f64>) {
    let (w, h) = (hi.0 - lo.0, hi.1 - lo.1);
    let (pw, ph) = (f64::from(pixels.0.max(1)), f64::from(pixels.1.max(1)));
    let per_m = (pw / w).min(ph / h);
    let (fw, fh) = (pw / per_m, ph / per_m);
    let (cx, cy) = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
    (cx - fw / 2.0..cx + fw / 2.0, cy - fh / 2.0..cy + fh / 2.0)
}

/// The least clearance to an obstacle, or that none came near.
pub fn clearance(least_m: f64) -> String {
    if least_m.is_finite() {
        format!("min clearance {least_m:.2} m")
    } else {
        "no obstacle came near".to_string()
    }
}

fn trajectories<DB: DrawingBackend>(
    world: &World,
    report: &Report,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    pins: &[pins::Pin],
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let (lo, hi) = site_extent(world);
    let title = format!(
        "{} ({}, seed {}): {}; {} collisions, {}",
        report.scenario,
        report.firmware,
        report.seed,
        report.why,
        report.collisions,
        clearance(report.min_obstacle_clearance_m)
    );
    // The movers' line under the title: on one line the two outran the panel.
    let movers = (report.movers.count > 0).then(|| {
        format!(
            "{} movers: drove into {}, walked into {} standing, {} braking; least person clearance {}",
            report.movers.count,
            report.movers.drove_into,
            report.movers.walked_into_standing,
            report.movers.walked_into_braking,
            report
                .movers
                .min_person_clearance_m
                .map_or("—".to_string(), |c| format!("{c:.2} m"))
        )
    });
    let caption = if movers.is_some() { 50 } else { 25 };
    let area = area.titled(&title, ("sans-serif", 16))?;
    let mut builder = ChartBuilder::on(&area);
    if let Some(line) = movers {
        builder.caption(line, ("sans-serif", 14));
    }
    // The plot's own pixels: the panel less its title, caption, margins and labels.
    let (pw, ph) = area.dim_in_pixel();
    let plot = (pw.saturating_sub(70), ph.saturating_sub(80 + caption));
    let (xs, ys) = fitted(lo, hi, plot);
    let mut chart = builder
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(40)
        .build_cartesian_2d(xs, ys)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    draw_swept(&mut chart, world)?;
    draw_site(&mut chart, world)?;
    draw_movers(&mut chart, world, report)?;
    draw_marks(&mut chart, world)?;
    draw_paths(&mut chart, world)?;
    draw_snapshots(&mut chart, world)?;
    pins::on_map(&mut chart, world, pins)?;
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    pins::list(&area, pins)
}

/// What the brushes swept, under everything else: once in pale green, twice or more in a
/// deeper one, missed in pale red with each missed patch's bounds outlined.
fn draw_swept<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let Some(sweeping) = &world.recorder.sweeping else {
        return Ok(());
    };
    let shades = [
        RGBColor(250, 200, 200),
        RGBColor(200, 235, 200),
        RGBColor(150, 205, 150),
    ];
    let cell = base_station::coverage::grid::CELL;
    for (count, label) in [(1u8, "swept"), (2, "swept twice or more"), (0, "missed")] {
        let color = shades[count as usize];
        let runs = sweeping.grid().runs().into_iter().filter(|r| r.2 == count);
        chart
            .draw_series(runs.map(|(at, len, _)| {
                Rectangle::new([(at.x, at.y), (at.x + len, at.y + cell)], color.filled())
            }))?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 16, y + 4)], color.filled()));
    }
    let red = RGBColor(200, 40, 40);
    let missed = sweeping.report().swept.missed;
    chart.draw_series(missed.iter().filter(|m| m.area_m2 >= 0.5).map(|m| {
        Rectangle::new(
            [(m.min[0], m.min[1]), (m.max[0], m.max[1])],
            red.stroke_width(1),
        )
    }))?;
    Ok(())
}

/// The obstacles, the goal and the planned route.
fn draw_site<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let grey = RGBColor(120, 120, 120);
    for o in world.map.obstacles() {
        match o {
            Obstacle::Circle { center, radius } => {
                let pts = circle(center.x, center.y, *radius);
                chart.draw_series(std::iter::once(Polygon::new(pts, grey.filled())))?;
            }
            Obstacle::Segment { a, b } => {
                chart.draw_series(LineSeries::new(
                    [(a.x, a.y), (b.x, b.y)],
                    grey.stroke_width(3),
                ))?;
            }
            Obstacle::Polygon { points } => {
                let pts: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
                chart.draw_series(std::iter::once(Polygon::new(pts, grey.filled())))?;
            }
        }
    }
    if let Some(g) = world.station.guidance().planner().goal() {
        chart.draw_series(std::iter::once(Cross::new(
            (g.x, g.y),
            8,
            BLACK.stroke_width(2),
        )))?;
    }
    if let Some(route) = world.station.route() {
        chart
            .draw_series(LineSeries::new(
                route.points.iter().map(|p| (p.x, p.y)),
                BLACK.mix(0.5).stroke_width(1),
            ))?
            .label("planned route")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.mix(0.5)));
    }
    Ok(())
}

/// The station's marks (what it sensed that the map does not show, and the room it keeps
/// round a person who stopped): every mark it held at some time in the run, once each, in
/// violet (the tracks' orange is beside them), over the movers. Where marks stood long or
/// came again, the shade is the same: the figure says where the route was kept out, the
/// recording's `/sensed` says when.
fn draw_marks<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let violet = RGBColor(150, 80, 210);
    // As one circle each, not a polygon: a crowd's run holds a few thousand marks.
    let (x0, x1) = (
        chart.backend_coord(&(0.0, 0.0)).0,
        chart.backend_coord(&(1.0, 0.0)).0,
    );
    let per_metre = f64::from(x1 - x0);
    let mut seen = std::collections::BTreeSet::new();
    let mut first = true;
    for o in world.sensed.iter().flat_map(|(_, marks)| marks) {
        let Obstacle::Circle { center, radius } = o else {
            continue;
        };
        if !seen.insert([center.x, center.y, *radius].map(f64::to_bits)) {
            continue;
        }
        let r = (radius * per_metre).round().max(1.0) as i32;
        let disc = Circle::new((center.x, center.y), r, violet.mix(0.12).filled());
        let series = chart.draw_series(std::iter::once(disc))?;
        if std::mem::take(&mut first) {
            series
                .label("marks (station): sensed, off the map, held at some time")
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 4), (x + 16, y + 4)], violet.mix(0.6).filled())
                });
        }
    }
    Ok(())
}

/// Each robot's path.
fn draw_paths<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let rec = &world.recorder;
    for (i, robot) in world.robots.iter().enumerate() {
        let label = match robot.role {
            Role::Leader => format!("leader {}", robot.id),
            Role::Follower => format!("follower {}", robot.id),
        };
        chart
            .draw_series(LineSeries::new(
                rec.samples.iter().map(|s| (s.robots[i].x, s.robots[i].y)),
                color(i).stroke_width(2),
            ))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 16, y)], color(i).stroke_width(2))
            });
    }
    Ok(())
}

/// A mover's footprint outline, closed.
fn outline(m: &MoverState) -> Vec<(f64, f64)> {
    match m.shape {
        MoverShape::Circle { radius } => circle(m.position.x, m.position.y, radius),
        MoverShape::Rectangle { length, width } => {
            let (l, w) = (0.5 * length, 0.5 * width);
            [(l, w), (-l, w), (-l, -w), (l, -w), (l, w)]
                .iter()
                .map(|(x, y)| {
                    let p = m.position + DVec2::new(*x, *y).rotate(DVec2::from_angle(m.heading));
                    (p.x, p.y)
                })
                .collect()
        }
    }
}

/// The movers (the truth) while they were near the fleet (within [`NEAR_FLEET_M`] of a
/// robot): their ways in grey, their footprints every 10 s, a red cross where one touched
/// a robot; the station's moving tracks near the fleet every 10 s in orange, with a line
/// to where their velocity takes them in a second. A plaza's crowd drawn whole buries the
/// fleet.
fn draw_movers<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
    report: &Report,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    if world.movers.is_empty() {
        return Ok(());
    }
    draw_ways(chart, world)?;
    draw_tracks(chart, world)?;
    for c in &report.movers.contacts {
        let near = sample_at(world, c.at_s);
        let Some(m) = near.and_then(|s| s.movers.iter().find(|m| m.index == c.mover)) else {
            continue;
        };
        chart.draw_series(std::iter::once(Cross::new(
            (m.position.x, m.position.y),
            6,
            RED.stroke_width(2),
        )))?;
    }
    Ok(())
}

/// Near the fleet: within this of a robot, m.
const NEAR_FLEET_M: f64 = 3.0;

/// Whether `p` is within [`NEAR_FLEET_M`] of a robot of `s`.
fn near_fleet(s: &crate::metrics::Sample, p: DVec2) -> bool {
    s.robots
        .iter()
        .any(|r| p.distance(DVec2::new(r.x, r.y)) <= NEAR_FLEET_M)
}

/// The sample nearest the time `t_s`.
fn sample_at(world: &World, t_s: f64) -> Option<&crate::metrics::Sample> {
    world
        .recorder
        .samples
        .iter()
        .min_by(|a, b| (a.t - t_s).abs().total_cmp(&(b.t - t_s).abs()))
}

/// The samples every `period` s.
fn every(world: &World, period: f64) -> impl Iterator<Item = &crate::metrics::Sample> {
    let step = (period * 10.0) as u64;
    world
        .recorder
        .samples
        .iter()
        .filter(move |s| ((s.t * 10.0).round() as u64).is_multiple_of(step))
}

/// Each mover's way while near the fleet (in pieces), and its footprint every 10 s there.
fn draw_ways<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let grey = RGBColor(90, 90, 90);
    let mut pieces: Vec<Vec<Vec<(f64, f64)>>> = vec![vec![Vec::new()]; world.movers.len()];
    for s in &world.recorder.samples {
        for m in &s.movers {
            let Some(way) = pieces.get_mut(m.index) else {
                continue;
            };
            match (near_fleet(s, m.position), way.last_mut()) {
                (true, Some(piece)) => piece.push((m.position.x, m.position.y)),
                (false, Some(piece)) if !piece.is_empty() => way.push(Vec::new()),
                _ => {}
            }
        }
    }
    let shown = pieces
        .iter()
        .filter(|w| w.iter().any(|p| p.len() > 1))
        .count();
    let label = format!(
        "movers (truth) within {NEAR_FLEET_M:.0} m of the fleet ({shown} of {}): ways, footprints every 10 s",
        world.movers.len()
    );
    let mut first = true;
    for piece in pieces.into_iter().flatten().filter(|p| p.len() > 1) {
        let series = chart.draw_series(LineSeries::new(piece, grey.mix(0.6)))?;
        if std::mem::take(&mut first) {
            series
                .label(label.clone())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], grey));
        }
    }
    for s in every(world, 10.0) {
        for m in s.movers.iter().filter(|m| near_fleet(s, m.position)) {
            chart.draw_series(std::iter::once(Polygon::new(outline(m), grey.mix(0.5))))?;
        }
    }
    Ok(())
}

/// The station's moving tracks near the fleet every 10 s.
fn draw_tracks<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let orange = RGBColor(240, 140, 0);
    let mut first = true;
    for s in every(world, 10.0) {
        let near = s
            .tracks
            .iter()
            .filter(|t| t.motion == Motion::Moving && near_fleet(s, t.position));
        for t in near {
            let (p, q) = (t.position, t.at(1.0));
            let series = chart.draw_series([
                PathElement::new([(p.x, p.y), (q.x, q.y)], orange.stroke_width(2)),
                PathElement::new(circle(p.x, p.y, t.radius.max(0.15)), orange.stroke_width(1)),
            ])?;
            if std::mem::take(&mut first) {
                series
                    .label("tracks (station) near the fleet: velocity × 1 s, every 10 s")
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 16, y)], orange.stroke_width(2))
                    });
            }
        }
    }
    Ok(())
}

/// Formation snapshots every 10 s: the robots' footprints joined leader → followers, the
/// time beside the leader.
fn draw_snapshots<'a, DB: DrawingBackend + 'a>(
    chart: &mut TimeChart<'a, DB>,
    world: &World,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let leader = world.robots.iter().position(|r| r.role == Role::Leader);
    for s in every(world, 10.0) {
        if let Some(l) = leader {
            let lp = (s.robots[l].x, s.robots[l].y);
            for (i, r) in s.robots.iter().enumerate() {
                if i != l {
                    chart.draw_series(LineSeries::new([lp, (r.x, r.y)], BLACK.mix(0.3)))?;
                }
            }
            let style = ("sans-serif", 11).into_font().color(&BLACK.mix(0.7));
            chart.draw_series(std::iter::once(
                EmptyElement::at(lp) + Text::new(format!("{:.0} s", s.t), (6, 6), style),
            ))?;
        }
        for (i, r) in s.robots.iter().enumerate() {
            let fp = world.robots[i].body.params.footprint;
            chart.draw_series(LineSeries::new(circle(r.x, r.y, fp), color(i).mix(0.8)))?;
        }
    }
    Ok(())
}

fn errors<DB: DrawingBackend>(
    world: &World,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    pins: &[pins::Pin],
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let rec = &world.recorder;
    let t_end = rec.samples.last().map_or(1.0, |s| s.t);
    let e_max = rec
        .samples
        .iter()
        .flat_map(|s| s.robots.iter().filter_map(|r| r.error))
        .fold(0.1f64, f64::max)
        .min(2.0);
    let mut chart = time_chart(
        world,
        area,
        "tracking error (control point to slot point)",
        0.0..e_max * 1.05,
    )?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc("error (m)")
        .draw()?;
    chart
        .draw_series(LineSeries::new([(0.0, 0.1), (t_end, 0.1)], BLACK.mix(0.4)))?
        .label("0.1 m: the stable-phase bound")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.mix(0.4)));
    // Shade transformations (blend strictly between the shapes).
    let band = RGBColor(255, 220, 150).mix(0.5);
    chart
        .draw_series(
            rec.samples
                .iter()
                .filter(|s| s.blend > 0.0 && s.blend < 1.0)
                .map(|s| {
                    Rectangle::new(
                        [(s.t - 0.05, 0.0), (s.t + 0.05, e_max * 1.05)],
                        band.filled(),
                    )
                }),
        )?
        .label("a shape change under way")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], band.filled()));
    pins::on_time(&mut chart, pins, 0.0..e_max * 1.05)?;
    for (i, robot) in world.robots.iter().enumerate() {
        if robot.role != Role::Follower {
            continue;
        }
        chart
            .draw_series(LineSeries::new(
                rec.samples
                    .iter()
                    .filter_map(|s| s.robots[i].error.map(|e| (s.t, e.min(e_max * 1.05)))),
                color(i).stroke_width(2),
            ))?
            .label(format!("follower {}", robot.id))
            .legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 16, y)], color(i).stroke_width(2))
            });
    }
    legend(&mut chart, SeriesLabelPosition::MiddleRight)
}

fn velocities<DB: DrawingBackend>(
    world: &World,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    pins: &[pins::Pin],
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let rec = &world.recorder;
    let mut chart = time_chart(
        world,
        area,
        "v (solid, m/s) and ω (dashed, rad/s)",
        -1.0..1.0,
    )?;
    chart.configure_mesh().x_desc("t (s)").draw()?;
    pins::on_time(&mut chart, pins, -1.0..1.0)?;
    for (i, robot) in world.robots.iter().enumerate() {
        let who = match robot.role {
            Role::Leader => format!("leader {}: v solid, ω dashed", robot.id),
            Role::Follower => format!("follower {}", robot.id),
        };
        chart
            .draw_series(LineSeries::new(
                rec.samples
                    .iter()
                    .map(|s| (s.t, s.robots[i].v.clamp(-1.0, 1.0))),
                color(i).stroke_width(2),
            ))?
            .label(who)
            .legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 16, y)], color(i).stroke_width(2))
            });
        chart.draw_series(DashedLineSeries::new(
            rec.samples
                .iter()
                .map(|s| (s.t, s.robots[i].omega.clamp(-1.0, 1.0))),
            4,
            3,
            color(i).into(),
        ))?;
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)
}
