//! Scatter plots of error against time (the speed/accuracy trade), with the
//! Pareto front drawn through the configurations nothing else beats.

use crate::picture::Picture;

/// One measured configuration on a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// The method's name: one colour per method.
    pub series: String,
    /// Time, ms (the x axis, log scale).
    pub time_ms: f64,
    /// Error (the y axis, linear from 0).
    pub error: f64,
}

/// Indices of the points on the Pareto front (no other point is both at
/// least as fast and at least as accurate, and strictly better in one),
/// ordered by time. Non-finite points are never on it.
pub fn pareto_front(points: &[Point]) -> Vec<usize> {
    let finite = |p: &Point| p.time_ms.is_finite() && p.error.is_finite();
    let mut order: Vec<usize> = (0..points.len()).filter(|&i| finite(&points[i])).collect();
    order.sort_by(|&a, &b| {
        let (pa, pb) = (&points[a], &points[b]);
        pa.time_ms.total_cmp(&pb.time_ms).then(pa.error.total_cmp(&pb.error))
    });
    let mut front = vec![];
    let mut best = f64::INFINITY;
    for i in order {
        // Sorted by time then error: a point joins when it beats every faster one.
        if points[i].error < best {
            best = points[i].error;
            front.push(i);
        }
    }
    front
}

/// Distinct colours for up to twelve series, then they repeat.
pub const PALETTE: [[u8; 3]; 12] = [
    [230, 90, 70],
    [240, 190, 60],
    [90, 200, 110],
    [80, 160, 240],
    [190, 110, 230],
    [230, 230, 230],
    [60, 210, 210],
    [240, 130, 190],
    [150, 150, 90],
    [250, 150, 60],
    [120, 120, 250],
    [170, 230, 140],
];

const AXIS: [u8; 3] = [150, 150, 160];
const GRID: [u8; 3] = [44, 46, 56];
const FRONT: [u8; 3] = [120, 120, 130];

/// Error against time: one colour per series (in order of first
/// appearance), time on a log axis, the Pareto front as a grey line, a
/// legend on the right.
pub fn pareto_plot(title: &str, time_label: &str, error_label: &str, points: &[Point]) -> Picture {
    let (w, h) = (760u32, 420u32);
    let (left, right, top, bottom) = (64u32, 560u32, 36u32, 360u32);
    let mut pic = Picture::new(w, h, [20, 22, 30]);
    pic.text(title, 10, 8, 2, [235, 235, 235]);
    let mut series: Vec<&str> = vec![];
    for p in points {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    let finite: Vec<&Point> = points.iter().filter(|p| p.time_ms.is_finite() && p.time_ms > 0.0).collect();
    let finite_err = || finite.iter().map(|p| p.error).filter(|e| e.is_finite());
    let (t_lo, t_hi) =
        finite.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| (lo.min(p.time_ms), hi.max(p.time_ms)));
    let (t_lo, t_hi) = if t_lo.is_finite() { (t_lo / 1.25, t_hi * 1.25) } else { (1.0, 10.0) };
    let e_hi = finite_err().fold(0.0f64, f64::max).max(1e-4) * 1.1;
    let x_of = |t: f64| left as f64 + (t.ln() - t_lo.ln()) / (t_hi.ln() - t_lo.ln()).max(1e-9) * (right - left) as f64;
    let y_of = |e: f64| bottom as f64 - (e / e_hi).clamp(0.0, 1.05) * (bottom - top) as f64;
    // Grid: decades and their 1.5–7× steps on the time axis, fifths on the error axis.
    let mut decade = 10f64.powf(t_lo.log10().floor());
    while decade <= t_hi {
        for m in [1.0, 1.5, 2.0, 3.0, 5.0, 7.0] {
            let t = decade * m;
            if t >= t_lo && t <= t_hi {
                let x = x_of(t) as u32;
                pic.vline(x, top, bottom, GRID);
                pic.text(&trim(t), x.saturating_sub(8), bottom + 6, 1, AXIS);
            }
        }
        decade *= 10.0;
    }
    for k in 0..=5 {
        let e = e_hi / 1.1 * k as f64 / 5.0;
        let y = y_of(e) as u32;
        pic.hline(left, right, y, GRID);
        pic.text(&format!("{e:.3}"), 8, y.saturating_sub(2), 1, AXIS);
    }
    pic.hline(left, right, bottom, AXIS);
    pic.vline(left, top, bottom, AXIS);
    pic.text(time_label, left + 120, bottom + 22, 2, AXIS);
    pic.text(error_label, 8, top - 12, 1, AXIS);
    let front = pareto_front(points);
    for pair in front.windows(2) {
        let (a, b) = (&points[pair[0]], &points[pair[1]]);
        pic.line((x_of(a.time_ms), y_of(a.error)), (x_of(b.time_ms), y_of(b.error)), FRONT);
    }
    for p in &finite {
        if !p.error.is_finite() {
            continue;
        }
        let color = PALETTE[series.iter().position(|s| *s == p.series).unwrap_or(0) % PALETTE.len()];
        pic.disc(x_of(p.time_ms), y_of(p.error), 3.5, color);
    }
    for (i, s) in series.iter().enumerate() {
        let y = top + 8 + i as u32 * 18;
        pic.disc((right + 24) as f64, y as f64 + 4.0, 4.0, PALETTE[i % PALETTE.len()]);
        pic.text(s, right + 36, y, 2, [220, 220, 220]);
    }
    let y = top + 8 + series.len() as u32 * 18 + 6;
    pic.hline(right + 18, right + 30, y + 4, FRONT);
    pic.text("pareto front", right + 36, y, 2, [220, 220, 220]);
    pic
}

/// A tick label without needless digits.
fn trim(t: f64) -> String {
    if t >= 10.0 {
        format!("{t:.0}")
    } else if t >= 1.0 {
        format!("{t:.1}")
    } else {
        format!("{t:.2}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(series: &str, time_ms: f64, error: f64) -> Point {
        Point { series: series.into(), time_ms, error }
    }

    #[test]
    fn the_front_keeps_only_undominated_points_in_time_order() {
        let points = vec![
            p("a", 10.0, 0.05),
            p("b", 5.0, 0.10),
            p("c", 20.0, 0.08), // slower and worse than a: dominated
            p("d", 30.0, 0.01),
            p("e", 5.0, 0.20), // as fast as b and worse: dominated
            p("f", 1.0, f64::NAN),
        ];
        assert_eq!(pareto_front(&points), vec![1, 0, 3]);
    }

    #[test]
    fn a_point_equal_in_time_and_error_to_a_front_point_is_not_added_twice() {
        let points = vec![p("a", 1.0, 0.1), p("b", 1.0, 0.1)];
        assert_eq!(pareto_front(&points).len(), 1);
    }

    #[test]
    fn the_plot_draws_each_series_in_its_own_colour() {
        let points = vec![p("hard", 2.0, 0.2), p("fins", 6.0, 0.02), p("fins", 12.0, 0.01)];
        let pic = pareto_plot("t", "ms", "mae", &points);
        let count = |c: [u8; 3]| pic.pixels.iter().filter(|px| **px == c).count();
        // Markers and legend dots: both colours present, generously.
        assert!(count(PALETTE[0]) > 40, "first series missing");
        assert!(count(PALETTE[1]) > 60, "second series missing");
        assert!(count(FRONT) > 20, "front line missing");
        assert_eq!(count(PALETTE[2]), 0, "no third series");
    }
}
