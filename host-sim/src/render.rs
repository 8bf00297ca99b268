//! Pictures of one episode: an animated GIF of the cart and pole, and a PNG of x, theta and
//! the commands over time ([`crate::batch`] puts a command's pictures in place).

use std::path::Path;

use anyhow::{Result, anyhow};
use firmware::cartpole::Params;
use host_common::plot::{FONT, ensure_font};
use plotters::coord::Shift;
use plotters::prelude::*;

use twin::Frame;

/// Pixels per metre in the animation; the track is drawn to scale.
const PX_PER_M: f64 = 100.0;
/// The narrowest animation, pixels.
const MIN_WIDTH_PX: f64 = 500.0;

/// What went wrong in drawing, in the system's words ([`reason`]): plotters' bitmap errors
/// show their cause only through Debug text, which no message carries.
fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!(reason(&format!("{e:?}")))
}

/// The system's own words for the failure `text` tells of (`File too large (os error 27)`),
/// found by its error number, as Debug text (`Os { code: 27, .. }`) or Display text shows
/// it (the last such: a path before it may spell one); a plain statement where it names none.
pub fn reason(text: &str) -> String {
    let code = ["Os { code: ", "(os error "].iter().find_map(|mark| {
        let rest = &text[text.rfind(mark)? + mark.len()..];
        let end = rest
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(rest.len());
        rest[..end].parse::<i32>().ok()
    });
    match code {
        Some(c) => std::io::Error::from_raw_os_error(c).to_string(),
        None => "the picture could not be drawn or encoded".into(),
    }
}

/// The failure `e` of writing the picture `path` (named as the user gave it, not by its
/// temporary name): the system's, exit status 1.
pub fn failed_writing(path: &Path, e: &anyhow::Error) -> weights::Error {
    weights::Error::Io(format!(
        "writing {}: {}",
        weights::shown(path),
        weights::excerpt(&format!("{e:#}"))
    ))
}

/// The animation's frame: the track, with room for the pole above it and, where the pole
/// hangs in some frame (a start-up), below it; a short track drawn larger.
struct Canvas {
    half_track: f64,
    pole: f64,
    px_per_m: f64,
    below: f64,
    w: u32,
    h: u32,
}

impl Canvas {
    fn of(frames: &[Frame], params: &Params) -> Canvas {
        let half_track = params.x_threshold + 0.3;
        let pole = 2.0 * params.length;
        let px_per_m = PX_PER_M.max(MIN_WIDTH_PX / (2.0 * half_track));
        let hangs = frames.iter().any(|f| f.state.theta.cos() < 0.0);
        let below = if hangs { pole } else { 0.0 };
        Canvas {
            half_track,
            pole,
            px_per_m,
            below,
            w: (2.0 * half_track * px_per_m) as u32,
            h: ((pole + 0.6 + below) * px_per_m) as u32,
        }
    }
}

/// Writes an animated GIF of `frames` (every `stride`-th period, in real time). A failure
/// says only what failed: the caller names the file ([`failed_writing`]), which `path`, a
/// temporary name, is not.
pub fn gif(
    path: &Path,
    frames: &[Frame],
    params: &Params,
    stride: usize,
    title: &str,
) -> Result<()> {
    ensure_font()?;
    let Canvas {
        half_track,
        pole,
        px_per_m,
        below,
        w,
        h,
    } = Canvas::of(frames, params);
    let delay_ms = (stride as f64 * params.tau * 1000.0).round() as u32;
    let root = BitMapBackend::gif(path, (w, h), delay_ms)
        .map_err(err)?
        .into_drawing_area();
    let to_px = |x: f64, y: f64| -> (i32, i32) {
        (
            ((x + half_track) * px_per_m).round() as i32,
            (f64::from(h) - (y + 0.3 + below) * px_per_m).round() as i32,
        )
    };
    let font = (FONT, 15).into_font();
    for (i, f) in frames.iter().enumerate().step_by(stride.max(1)) {
        root.fill(&WHITE).map_err(err)?;
        let (x, theta) = (f.state.x, f.state.theta);
        // Track with the failure limits.
        root.draw(&PathElement::new(
            [to_px(-half_track, 0.0), to_px(half_track, 0.0)],
            BLACK.stroke_width(2),
        ))
        .map_err(err)?;
        for edge in [-params.x_threshold, params.x_threshold] {
            root.draw(&PathElement::new(
                [to_px(edge, -0.15), to_px(edge, 0.15)],
                RED.stroke_width(2),
            ))
            .map_err(err)?;
        }
        // Cart, coloured by the push it is given, and the pole.
        let colour = match f.command.level() {
            d if d > 0.0 => RGBColor(40, 110, 200),
            d if d < 0.0 => RGBColor(230, 130, 30),
            _ => RGBColor(128, 128, 128),
        };
        root.draw(&Rectangle::new(
            [to_px(x - 0.25, 0.12), to_px(x + 0.25, -0.08)],
            colour.filled(),
        ))
        .map_err(err)?;
        let tip = (x + pole * theta.sin(), 0.12 + pole * theta.cos());
        root.draw(&PathElement::new(
            [to_px(x, 0.12), to_px(tip.0, tip.1)],
            RGBColor(140, 80, 40).stroke_width(6),
        ))
        .map_err(err)?;
        root.draw(&Circle::new(to_px(x, 0.12), 4, BLACK.filled()))
            .map_err(err)?;
        let t = (i + 1) as f64 * params.tau;
        root.draw(&Text::new(
            format!(
                "{title}   t = {t:5.2} s   x = {x:+.2} m   theta = {:+.1} deg",
                theta.to_degrees()
            ),
            (8, 6),
            font.clone(),
        ))
        .map_err(err)?;
        root.present().map_err(err)?;
    }
    Ok(())
}

/// Writes a PNG with three panels over time: cart position, pole angle, and the command;
/// a failure as [`gif`]'s.
pub fn timeseries(path: &Path, frames: &[Frame], params: &Params, title: &str) -> Result<()> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (1000, 720)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, (FONT, 22).into_font()).map_err(err)?;
    let panels = root.split_evenly((3, 1));
    let t_end = frames.len() as f64 * params.tau;
    let series = |f: &dyn Fn(&Frame) -> f64| -> Vec<(f64, f64)> {
        frames
            .iter()
            .enumerate()
            .map(|(i, fr)| ((i + 1) as f64 * params.tau, f(fr)))
            .collect()
    };
    let x_lim = params.x_threshold;
    let th_lim = params.theta_threshold_radians.to_degrees();
    // The angle about upright in one turn, drawn on its whole range once it leaves the
    // failure limits (a swing-up).
    let theta = |f: &Frame| f.state.theta.sin().atan2(f.state.theta.cos()).to_degrees();
    let th_range = frames.iter().map(theta).fold(th_lim, |m, t| m.max(t.abs()));
    panel(
        &panels[0],
        t_end,
        (-x_lim, x_lim),
        "x (m)",
        &[series(&|f| f.state.x)],
        x_lim,
    )?;
    panel(
        &panels[1],
        t_end,
        (-th_range, th_range),
        "theta (deg)",
        &turns(series(&theta)),
        th_lim,
    )?;
    let command = series(&|f| f64::from(f.command.level()));
    let mut chart = ChartBuilder::on(&panels[2])
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, -1.3..1.3)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("push (+1 right)")
        .label_style((FONT, 14))
        .y_labels(3)
        .draw()
        .map_err(err)?;
    // A step plot: the command holds for the whole period.
    let steps: Vec<(f64, f64)> = command
        .iter()
        .flat_map(|&(t, v)| [(t - params.tau, v), (t, v)])
        .collect();
    chart
        .draw_series(LineSeries::new(steps, BLUE.stroke_width(1)))
        .map_err(err)?;
    root.present().map_err(err)
}

fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    t_end: f64,
    (lo, hi): (f64, f64),
    label: &str,
    lines: &[Vec<(f64, f64)>],
    limit: f64,
) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, lo * 1.05..hi * 1.05)
        .map_err(err)?;
    chart
        .configure_mesh()
        .y_desc(label)
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    for l in [-limit, limit] {
        chart
            .draw_series(LineSeries::new([(0.0, l), (t_end, l)], RED.mix(0.6)))
            .map_err(err)?;
    }
    for line in lines {
        chart
            .draw_series(LineSeries::new(line.iter().copied(), BLUE.stroke_width(2)))
            .map_err(err)?;
    }
    Ok(())
}

/// The angle's line cut where it crosses the bottom (+-180 degrees), so it is not joined
/// across the panel: a wide line turned back on itself there draws a spike out of the panel.
fn turns(points: Vec<(f64, f64)>) -> Vec<Vec<(f64, f64)>> {
    let mut lines: Vec<Vec<(f64, f64)>> = Vec::new();
    for p in points {
        match lines.last_mut() {
            Some(line) if line.last().is_some_and(|q| (p.1 - q.1).abs() <= 180.0) => line.push(p),
            _ => lines.push(vec![p]),
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::{ControllerKind, Net, episode};
    use twin::Scenario;

    #[test]
    fn writes_a_gif_and_a_png_that_decode() {
        let dir = std::env::temp_dir().join(format!("host-sim-render-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut frames = Vec::new();
        let s = Scenario::nominal();
        episode(ControllerKind::Policy, &Net::shipped(), &s, 60, 0, 0, |f| {
            frames.push(f)
        });
        let (g, p) = (dir.join("e.gif"), dir.join("e.png"));
        gif(&g, &frames, &s.params, 2, "policy").unwrap();
        timeseries(&p, &frames, &s.params, "policy").unwrap();
        let mut decoder = gif::DecodeOptions::new()
            .read_info(std::fs::File::open(&g).unwrap())
            .unwrap();
        let (w, h) = (decoder.width(), decoder.height());
        // 2 * (2.4 + 0.3) m and 1.0 + 0.6 m at 100 px/m.
        assert_eq!((w, h), (540, 160));
        let mut n = 0;
        while decoder.read_next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, frames.len().div_ceil(2));
        let png = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()))
            .read_info()
            .unwrap();
        assert_eq!((png.info().width, png.info().height), (1000, 720));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_angle_line_is_cut_only_where_it_crosses_the_bottom() {
        let t = |v: &[f64]| -> Vec<(f64, f64)> {
            v.iter().enumerate().map(|(i, &y)| (i as f64, y)).collect()
        };
        let lines = turns(t(&[170.0, 179.0, -179.0, -170.0, -90.0, 0.0, 90.0, 179.5]));
        let ys: Vec<Vec<f64>> = lines
            .iter()
            .map(|l| l.iter().map(|p| p.1).collect())
            .collect();
        assert_eq!(
            ys,
            [
                vec![170.0, 179.0],
                vec![-179.0, -170.0, -90.0, 0.0, 90.0, 179.5]
            ]
        );
        assert!(turns(Vec::new()).is_empty());
    }
}
