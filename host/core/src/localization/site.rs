//! The site frame on the globe: an origin (latitude, longitude) and the compass bearing of
//! the site's x axis. Exact WGS84 (geodetic → local east-north-up), not a flat-earth
//! approximation: a site a kilometre across stays within millimetres.

use glam::DVec2;
use map_3d::Ellipsoid;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteOrigin {
    /// WGS84 latitude of the site's (0, 0), degrees north.
    pub lat_deg: f64,
    /// WGS84 longitude of the site's (0, 0), degrees east.
    pub lon_deg: f64,
    /// Compass bearing of the site's x axis, degrees clockwise from true north (90: the x
    /// axis points east, and then y points north).
    #[serde(default = "east")]
    pub x_axis_bearing_deg: f64,
}

fn east() -> f64 {
    90.0
}

impl SiteOrigin {
    /// A WGS84 position (degrees) in the site frame, m.
    pub fn to_site(&self, lat_deg: f64, lon_deg: f64) -> DVec2 {
        let (e, n, _) = map_3d::geodetic2enu(
            lat_deg.to_radians(),
            lon_deg.to_radians(),
            0.0,
            self.lat_deg.to_radians(),
            self.lon_deg.to_radians(),
            0.0,
            Ellipsoid::WGS84,
        );
        let (s, c) = self.x_axis_bearing_deg.to_radians().sin_cos();
        // x̂ = (sin b, cos b) and ŷ = (−cos b, sin b) in (east, north).
        DVec2::new(e * s + n * c, -e * c + n * s)
    }

    /// A site position back to WGS84 (degrees).
    pub fn to_wgs84(&self, p: DVec2) -> (f64, f64) {
        let (s, c) = self.x_axis_bearing_deg.to_radians().sin_cos();
        let e = p.x * s - p.y * c;
        let n = p.x * c + p.y * s;
        let (lat, lon, _) = map_3d::enu2geodetic(
            e,
            n,
            0.0,
            self.lat_deg.to_radians(),
            self.lon_deg.to_radians(),
            0.0,
            Ellipsoid::WGS84,
        );
        (lat.to_degrees(), lon.to_degrees())
    }

    /// A true heading (degrees clockwise from north) as a site heading (rad,
    /// counter-clockwise from x).
    pub fn heading_to_site(&self, true_deg: f64) -> f64 {
        crate::geometry::wrap_angle((self.x_axis_bearing_deg - true_deg).to_radians())
    }

    /// A site heading (rad) as a true heading, degrees in [0, 360).
    pub fn heading_to_true(&self, site_rad: f64) -> f64 {
        (self.x_axis_bearing_deg - site_rad.to_degrees()).rem_euclid(360.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ZURICH: SiteOrigin = SiteOrigin {
        lat_deg: 47.3769,
        lon_deg: 8.5417,
        x_axis_bearing_deg: 90.0,
    };

    #[test]
    fn north_and_east_of_the_origin_are_y_and_x_when_x_points_east() {
        // 0.001° of latitude is 111.2 m at 47° N; 0.001° of longitude 75.5 m.
        let p = ZURICH.to_site(47.3779, 8.5417);
        assert!(p.x.abs() < 1e-3 && (p.y - 111.2).abs() < 0.2, "{p}");
        let p = ZURICH.to_site(47.3769, 8.5427);
        assert!((p.x - 75.5).abs() < 0.2 && p.y.abs() < 0.01, "{p}");
    }

    #[test]
    fn a_rotated_site_round_trips_to_the_millimetre() {
        let site = SiteOrigin {
            x_axis_bearing_deg: 33.0,
            ..ZURICH
        };
        for p in [
            DVec2::new(0.0, 0.0),
            DVec2::new(12.3, -45.6),
            DVec2::new(800.0, 600.0),
        ] {
            let (lat, lon) = site.to_wgs84(p);
            let back = site.to_site(lat, lon);
            assert!((back - p).length() < 1e-3, "{p} → {back}");
        }
        // Heading: the x axis's bearing is heading 0; 90° more clockwise is −π/2.
        assert!(site.heading_to_site(33.0).abs() < 1e-12);
        assert!((site.heading_to_site(123.0) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((site.heading_to_true(site.heading_to_site(250.0)) - 250.0).abs() < 1e-9);
    }
}
