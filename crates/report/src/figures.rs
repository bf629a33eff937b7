//! The figures, as inline SVG. Each returns a [`Figure`]: drawn (with an SVG), or not drawn
//! with a note that says why — a degenerate input never gives a broken chart.

use std::fmt::Write as _;

use crate::ctx::{AGG_ALL, Ctx};
use crate::draw::{
    AXIS, BLUES, DIVERGING, GRID, HEAD, LABEL, SMALL, Scale, Svg, band_colour, c, esc, fixed,
    group_colour, hex, ink_on, level, pct, ramp, sval, text_w, tick_label, ticks, val, y_axis,
};

/// One figure of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Element id (`fig-1`, `fig-2a`, …), stable across versions.
    pub id: &'static str,
    /// Label (`Figure 1`).
    pub label: &'static str,
    /// Short title.
    pub title: String,
    /// Caption (plain text).
    pub caption: String,
    /// The chart; `None` when the input cannot be drawn honestly.
    pub svg: Option<String>,
    /// Explanations shown under the figure (why it is missing, or what it leaves out).
    pub notes: Vec<String>,
}

impl Figure {
    fn missing(
        id: &'static str,
        label: &'static str,
        title: &str,
        caption: String,
        why: String,
    ) -> Self {
        Self {
            id,
            label,
            title: title.to_string(),
            caption,
            svg: None,
            notes: vec![why],
        }
    }

    /// The `<figure>` element.
    pub fn html(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "<figure class=\"fig\" id=\"{}\" data-drawn=\"{}\">",
            self.id,
            self.svg.is_some()
        );
        match &self.svg {
            Some(svg) => s.push_str(svg),
            None => {
                let _ = writeln!(
                    s,
                    "<div class=\"fig-missing\" role=\"note\">Not drawn: {}</div>",
                    esc(self.notes.first().map_or("", String::as_str))
                );
            }
        }
        let _ = writeln!(
            s,
            "<figcaption><strong>{}.</strong> {}</figcaption>",
            esc(self.label),
            esc(&self.caption)
        );
        let skip = usize::from(self.svg.is_none());
        for n in self.notes.iter().skip(skip) {
            let _ = writeln!(s, "<p class=\"note\">{}</p>", esc(n));
        }
        s.push_str("</figure>\n");
        s
    }
}

/// Figure 1: dose-response per scenario with bootstrap bands, the budget line and σ*.
pub(crate) fn dose_response(cx: &Ctx) -> Figure {
    const ID: &str = "fig-1";
    const LABEL_: &str = "Figure 1";
    let title = "Dose-response per scenario";
    let hb = cx.hb;
    let Some(axis) = cx.axis.clone() else {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            String::new(),
            "the envelope has no perturbation axis".into(),
        );
    };
    let levels: Vec<f64> = cx
        .env
        .axes
        .iter()
        .find(|a| a.axis == axis)
        .map(|a| a.levels.clone())
        .unwrap_or_default();
    let caption = format!(
        "Mean ΔADE (perturbed − clean ADE, m) against the {axis} level, per classified scenario and for all clips, \
         with bootstrap 95% bands. Dashed red: the {}% budget (b × mean clean ADE); grey: the all-clips curve; \
         vertical line: σ* ({} rule); filled red dots exceed the budget. All panels share one y scale \
         (pilot scenarios' bands may be clipped).",
        fixed(100.0 * hb, 0),
        cx.env.parameters.rule.name()
    );
    let mut groups: Vec<String> = cx
        .scenarios
        .iter()
        .filter(|s| !cx.dose(s, &axis).is_empty())
        .cloned()
        .collect();
    let agg = cx.dose(AGG_ALL, &axis);
    if !agg.is_empty() {
        groups.push(AGG_ALL.to_string());
    }
    if groups.is_empty() || levels.is_empty() {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            format!("no dose-response points on the axis {axis}"),
        );
    }
    let mut notes = Vec::new();
    if cx
        .env
        .dose_response
        .iter()
        .all(|d| d.delta_ade_ci95_m.is_none())
    {
        notes.push(
            "No confidence bands: the analysis ran without bootstrap resamples (--bootstrap 0)."
                .into(),
        );
    }
    let censored: Vec<&String> = groups
        .iter()
        .filter(|g| cx.headline(g).is_some_and(|t| t.right_censored))
        .collect();
    if censored.len() == groups.len() {
        notes.push(format!(
            "Every threshold is right-censored: no tested {axis} level exceeds the {}% budget for any group, \
             so the true thresholds may lie above {}; extend the grid to locate them.",
            fixed(100.0 * hb, 0),
            level(levels[levels.len() - 1])
        ));
    }
    // One y scale for all panels.
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for g in &groups {
        let pilot = cx.pilot(g);
        for d in cx.dose(g, &axis) {
            lo = lo.min(d.delta_ade_m);
            hi = hi.max(d.delta_ade_m).max(hb * d.mean_ade_clean_m);
            if let (false, Some([a, b])) = (pilot, d.delta_ade_ci95_m)
                && a.is_finite()
                && b.is_finite()
            {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
    }
    let pad = 0.06 * (hi - lo).max(1e-9);
    let (yt, ystep) = ticks(lo - pad, hi + pad, 4);
    let (ylo, yhi) = (yt[0], yt[yt.len() - 1]);

    let n = groups.len();
    let cols = n.min(4);
    let rows = n.div_ceil(cols);
    let (pw, ph) = (232.0, 178.0);
    let w = cols as f64 * pw + 20.0;
    let legend_h = 44.0;
    let h = rows as f64 * ph + legend_h + 24.0;
    let mut desc = format!(
        "Small multiples of mean ΔADE against the {axis} level ({}). ",
        levels
            .iter()
            .map(|l| level(*l))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut s = Svg::open(ID, w, h, &format!("Figure 1: {title}"));
    let nlev = levels.len();
    for (k, g) in groups.iter().enumerate() {
        let (col, row) = (k % cols, k / cols);
        let px = 10.0 + col as f64 * pw;
        let py = 6.0 + row as f64 * ph;
        let (x0, x1, y0, y1) = (px + 46.0, px + pw - 12.0, py + 30.0, py + ph - 34.0);
        let xs = |lv: f64| -> Option<f64> {
            levels
                .iter()
                .position(|l| *l == lv)
                .map(|i| x0 + (i as f64 + 0.5) / nlev as f64 * (x1 - x0))
        };
        let ys = Scale::new(ylo, yhi, y1, y0);
        let pts = cx.dose(g, &axis);
        let pilot = cx.pilot(g);
        let n_clips = cx.n_clips(g);
        let head = format!(
            "{}{}{}",
            if g == AGG_ALL {
                "ALL CLIPS"
            } else {
                g.as_str()
            },
            n_clips.map_or(String::new(), |n| format!(" · n = {n}")),
            if pilot { " · pilot" } else { "" }
        );
        s.text(px + 46.0, py + 14.0, "start", HEAD, &head);
        s.rect(
            x0,
            y0,
            x1 - x0,
            y1 - y0,
            "fill=\"#ffffff\" stroke=\"#c8c8c8\"",
        );
        y_axis(&mut s, &ys, &yt, ystep, x0, x1);
        if ylo < 0.0 && yhi > 0.0 {
            s.line(
                x0,
                ys.at(0.0),
                x1,
                ys.at(0.0),
                "stroke=\"#9a9a9a\" stroke-width=\"1\"",
            );
        }
        for &lv in &levels {
            if let Some(x) = xs(lv) {
                s.line(x, y1, x, y1 + 4.0, AXIS);
                s.text(x, y1 + 15.0, "middle", SMALL, &level(lv));
            }
        }
        s.text((x0 + x1) / 2.0, y1 + 28.0, "middle", SMALL, &axis);
        if col == 0 {
            s.vtext(px + 10.0, (y0 + y1) / 2.0, SMALL, "ΔADE (m)");
        }
        let clip = format!("{ID}-clip-{k}");
        s.raw(&format!(
            "<clipPath id=\"{clip}\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath>\n<g clip-path=\"url(#{clip})\">\n",
            c(x0),
            c(y0),
            c(x1 - x0),
            c(y1 - y0)
        ));
        // Bootstrap band.
        let with_ci: Vec<(f64, [f64; 2])> = pts
            .iter()
            .filter_map(|d| Some((xs(d.level)?, d.delta_ade_ci95_m?)))
            .filter(|(_, [a, b])| a.is_finite() && b.is_finite())
            .collect();
        if with_ci.len() == pts.len() && with_ci.len() >= 2 {
            let mut poly: Vec<(f64, f64)> =
                with_ci.iter().map(|(x, [_, b])| (*x, ys.at(*b))).collect();
            poly.extend(with_ci.iter().rev().map(|(x, [a, _])| (*x, ys.at(*a))));
            s.polygon(
                &poly,
                "fill=\"#1f4e79\" fill-opacity=\"0.16\" stroke=\"none\" class=\"ci-band\"",
            );
        } else if with_ci.len() == 1 {
            let (x, [a, b]) = with_ci[0];
            s.line(
                x,
                ys.at(a),
                x,
                ys.at(b),
                "stroke=\"#1f4e79\" stroke-opacity=\"0.4\" stroke-width=\"6\"",
            );
        }
        // Budget line.
        let budget: Vec<(f64, f64)> = pts
            .iter()
            .filter_map(|d| Some((xs(d.level)?, ys.at(hb * d.mean_ade_clean_m))))
            .collect();
        s.polyline(
            &budget,
            "stroke=\"#c0392b\" stroke-width=\"1.3\" stroke-dasharray=\"5 3\" class=\"budget\"",
        );
        // The aggregate for comparison.
        if g != AGG_ALL {
            let a: Vec<(f64, f64)> = agg
                .iter()
                .filter_map(|d| Some((xs(d.level)?, ys.at(d.delta_ade_m))))
                .collect();
            s.polyline(
                &a,
                "stroke=\"#8c8c8c\" stroke-width=\"1.2\" stroke-dasharray=\"2 2\"",
            );
        }
        let line: Vec<(f64, f64)> = pts
            .iter()
            .filter_map(|d| Some((xs(d.level)?, ys.at(d.delta_ade_m))))
            .collect();
        let ink = if g == AGG_ALL { "#111111" } else { "#1f4e79" };
        s.polyline(
            &line,
            &format!("stroke=\"{ink}\" stroke-width=\"2\" class=\"curve\""),
        );
        s.raw("</g>\n");
        for d in &pts {
            let Some(x) = xs(d.level) else { continue };
            let pass = cx.passes(d);
            let tip = format!(
                "{} at {} {}: ΔADE {} m{}, clean ADE {} m, {} pairs; {} the {}% budget",
                Ctx::group_name(g),
                axis,
                level(d.level),
                sval(d.delta_ade_m),
                d.delta_ade_ci95_m.map_or(String::new(), |[a, b]| format!(
                    " [{}, {}]",
                    sval(a),
                    sval(b)
                )),
                val(d.mean_ade_clean_m),
                d.n_pairs,
                if pass { "within" } else { "over" },
                fixed(100.0 * hb, 0)
            );
            let style = if pass {
                format!("fill=\"#ffffff\" stroke=\"{ink}\" stroke-width=\"1.6\"")
            } else {
                "fill=\"#c0392b\" stroke=\"#7b1f16\" stroke-width=\"1\"".to_string()
            };
            s.dot(x, ys.at(d.delta_ade_m).clamp(y0, y1), 3.4, &style, &tip);
        }
        // σ*.
        let t = cx.headline(g);
        let mark = match t {
            None => "σ*: —".to_string(),
            Some(t) => match (t.sigma_star, t.right_censored) {
                (None, _) => format!("σ*: none (fails at {})", level(levels[0])),
                (Some(v), true) => format!("σ* ≥ {} (censored)", level(v)),
                (Some(v), false) => format!("σ* = {}", level(v)),
            },
        };
        if let Some(x) = t.and_then(|t| t.sigma_star).and_then(xs) {
            s.line(x, y0, x, y1, "stroke=\"#2e8b57\" stroke-width=\"1.5\" stroke-dasharray=\"4 2\" class=\"sigma-star\"");
            let (anchor, tx) = if x > (x0 + x1) / 2.0 {
                ("end", x - 3.0)
            } else {
                ("start", x + 3.0)
            };
            s.text(
                tx,
                y0 + 11.0,
                anchor,
                "fill=\"#1e6b41\" font-size=\"10\" font-weight=\"bold\"",
                &mark,
            );
            if t.is_some_and(|t| t.right_censored) {
                s.text(
                    x + 3.0,
                    (y0 + y1) / 2.0,
                    "start",
                    "fill=\"#1e6b41\" font-size=\"12\"",
                    "→",
                );
            }
        } else {
            s.text(
                x0 + 3.0,
                y0 + 11.0,
                "start",
                "fill=\"#7b1f16\" font-size=\"10\" font-weight=\"bold\"",
                &mark,
            );
        }
        let _ = write!(
            desc,
            "{}: ΔADE {} m at {} to {} m at {}; {}. ",
            Ctx::group_name(g),
            pts.first().map_or("—".into(), |d| sval(d.delta_ade_m)),
            pts.first().map_or("—".into(), |d| level(d.level)),
            pts.last().map_or("—".into(), |d| sval(d.delta_ade_m)),
            pts.last().map_or("—".into(), |d| level(d.level)),
            mark
        );
    }
    // Legend.
    let ly = h - legend_h + 8.0;
    let mut lx = 16.0;
    let mut item = |s: &mut Svg, sample: &str, text: &str, width: f64| {
        s.raw(
            &sample
                .replace("{x}", &c(lx))
                .replace("{x2}", &c(lx + 22.0))
                .replace("{y}", &c(ly))
                .replace("{yb}", &c(ly - 5.0)),
        );
        s.text(lx + 27.0, ly + 3.5, "start", LABEL, text);
        lx += width;
    };
    item(
        &mut s,
        "<line x1=\"{x}\" y1=\"{y}\" x2=\"{x2}\" y2=\"{y}\" stroke=\"#1f4e79\" stroke-width=\"2\"/>\n",
        "mean ΔADE",
        110.0,
    );
    item(
        &mut s,
        "<rect x=\"{x}\" y=\"{yb}\" width=\"22\" height=\"10\" fill=\"#1f4e79\" fill-opacity=\"0.16\"/>\n",
        "bootstrap 95%",
        125.0,
    );
    item(
        &mut s,
        "<line x1=\"{x}\" y1=\"{y}\" x2=\"{x2}\" y2=\"{y}\" stroke=\"#c0392b\" stroke-width=\"1.3\" stroke-dasharray=\"5 3\"/>\n",
        &format!("{}% budget", fixed(100.0 * hb, 0)),
        120.0,
    );
    item(
        &mut s,
        "<line x1=\"{x}\" y1=\"{y}\" x2=\"{x2}\" y2=\"{y}\" stroke=\"#8c8c8c\" stroke-width=\"1.2\" stroke-dasharray=\"2 2\"/>\n",
        "all clips",
        95.0,
    );
    item(
        &mut s,
        "<line x1=\"{x}\" y1=\"{y}\" x2=\"{x2}\" y2=\"{y}\" stroke=\"#2e8b57\" stroke-width=\"1.5\" stroke-dasharray=\"4 2\"/>\n",
        "σ*",
        60.0,
    );
    item(
        &mut s,
        "<circle cx=\"{x}\" cy=\"{y}\" r=\"3.4\" fill=\"#c0392b\" transform=\"translate(11 0)\"/>\n",
        "over budget",
        110.0,
    );
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes,
    }
}

fn normal_pdf(x: f64, mean: f64, sd: f64) -> f64 {
    let z = (x - mean) / sd;
    (-0.5 * z * z).exp() / (sd * (2.0 * std::f64::consts::PI).sqrt())
}

/// Figure 2a: L2 histogram of changed pairs with the mixture density and band boundaries,
/// and the BIC curve over k.
pub(crate) fn severity(cx: &Ctx) -> Figure {
    const ID: &str = "fig-2a";
    const LABEL_: &str = "Figure 2a";
    let title = "Severity bands of changed pairs";
    let sv = &cx.env.severity;
    let caption = format!(
        "Left: L2 deviation (m) of the {} changed-CoC pairs, histogram as a density, with the fitted {}-component \
         Gaussian mixture (black), its components (coloured by band) and the band boundaries where the \
         maximum-posterior band switches (dashed). Right: minimum BIC over restart seeds for each k, the chosen k marked.",
        sv.n_changed,
        sv.chosen_k.map_or("—".into(), |k| k.to_string())
    );
    let bands: Vec<_> = sv
        .bands
        .iter()
        .filter(|b| {
            b.mean_m.is_finite() && b.std_m.is_finite() && b.std_m > 0.0 && b.weight.is_finite()
        })
        .collect();
    if !sv.defined || bands.is_empty() {
        let why = sv
            .reason
            .clone()
            .unwrap_or_else(|| "no severity bands were fitted".into());
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            format!(
                "the severity mixture is undefined ({why}); with no changed pairs there is no L2 distribution to show."
            ),
        );
    }
    let mut notes = Vec::new();
    let k = bands.len();
    if k == 1 {
        notes.push(
            "A single band: one Gaussian describes the changed pairs' L2 best, so there are no band boundaries and \
             no high-severity bands (P(high) is undefined)."
                .into(),
        );
    }
    let sample: Option<Vec<f64>> = cx.changed_l2_m.map(|v| {
        v.iter()
            .copied()
            .filter(|x| x.is_finite() && *x >= 0.0)
            .collect()
    });
    let sample = sample.filter(|v| !v.is_empty());
    if sample.is_none() {
        notes.push(
            "No histogram: envelope.json does not hold the changed pairs' L2 values. Rebuild the report with the \
             pairs table (fogline report finds it at the envelope's input path when its checksum matches)."
                .into(),
        );
    }
    let xmax = match &sample {
        Some(v) => v.iter().copied().fold(0.0, f64::max) * 1.02,
        None => bands
            .iter()
            .map(|b| b.mean_m + 3.0 * b.std_m)
            .fold(0.0, f64::max),
    }
    .max(1e-6);
    let (w, h) = (960.0, 330.0);
    let (x0, x1, y0, y1) = (58.0, 610.0, 40.0, 280.0);
    let mut s = Svg::open(ID, w, h, &format!("Figure 2a: {title}"));
    // Histogram.
    let nb = cx.params.histogram_bins;
    let bw = xmax / nb as f64;
    let mut hist = vec![0usize; nb];
    if let Some(v) = &sample {
        for &x in v {
            hist[((x / bw) as usize).min(nb - 1)] += 1;
        }
    }
    let n_s = sample.as_ref().map_or(0, Vec::len) as f64;
    let dens: Vec<f64> = hist
        .iter()
        .map(|&c| {
            if n_s > 0.0 {
                c as f64 / (n_s * bw)
            } else {
                0.0
            }
        })
        .collect();
    let grid: Vec<f64> = (0..=400).map(|i| xmax * i as f64 / 400.0).collect();
    let mix = |x: f64| {
        bands
            .iter()
            .map(|b| b.weight * normal_pdf(x, b.mean_m, b.std_m))
            .sum::<f64>()
    };
    let mix_v: Vec<f64> = grid.iter().map(|&x| mix(x)).collect();
    let ymax = dens
        .iter()
        .copied()
        .chain(mix_v.iter().copied())
        .fold(0.0, f64::max)
        .max(1e-12);
    let (yt, ystep) = ticks(0.0, ymax * 1.05, 4);
    let xs = Scale::new(0.0, xmax, x0, x1);
    let ys = Scale::new(0.0, yt[yt.len() - 1], y1, y0);
    s.text(
        x0,
        16.0,
        "start",
        HEAD,
        &format!("L2 of changed pairs (n = {})", sv.n_changed),
    );
    s.rect(
        x0,
        y0,
        x1 - x0,
        y1 - y0,
        "fill=\"#ffffff\" stroke=\"#c8c8c8\"",
    );
    // Band regions along the top (maximum posterior at the midpoint of each region).
    let mut cuts: Vec<f64> = vec![0.0];
    cuts.extend(
        sv.boundaries_m
            .iter()
            .copied()
            .filter(|b| b.is_finite() && *b > 0.0 && *b < xmax),
    );
    cuts.push(xmax);
    for wdw in cuts.windows(2) {
        let mid = 0.5 * (wdw[0] + wdw[1]);
        let best = (0..k)
            .max_by(|&i, &j| {
                let pi = bands[i].weight * normal_pdf(mid, bands[i].mean_m, bands[i].std_m);
                let pj = bands[j].weight * normal_pdf(mid, bands[j].mean_m, bands[j].std_m);
                pi.total_cmp(&pj)
            })
            .unwrap_or(0);
        let (a, b) = (xs.at(wdw[0]), xs.at(wdw[1]));
        s.rect_tip(
            a,
            y0 - 14.0,
            b - a,
            12.0,
            &format!(
                "fill=\"{}\" stroke=\"#ffffff\" stroke-width=\"0.5\"",
                band_colour(best, k)
            ),
            &format!("{}: {} – {} m", bands[best].name, val(wdw[0]), val(wdw[1])),
        );
        if b - a > 22.0 {
            let rgb = ramp(
                &crate::draw::SEVERITY,
                if k <= 1 {
                    0.0
                } else {
                    best as f64 / (k - 1) as f64
                },
            );
            s.text(
                (a + b) / 2.0,
                y0 - 4.5,
                "middle",
                &format!(
                    "fill=\"{}\" font-size=\"9.5\" font-weight=\"bold\"",
                    ink_on(rgb)
                ),
                &bands[best].name,
            );
        }
    }
    y_axis(&mut s, &ys, &yt, ystep, x0, x1);
    let (xt, xstep) = ticks(0.0, xmax, 8);
    for &t in xt.iter().filter(|t| **t <= xmax) {
        let x = xs.at(t);
        s.line(x, y1, x, y1 + 4.0, AXIS);
        s.text(x, y1 + 15.0, "middle", SMALL, &tick_label(t, xstep));
    }
    s.text(
        (x0 + x1) / 2.0,
        y1 + 32.0,
        "middle",
        LABEL,
        "L2 deviation between clean and perturbed trajectories (m)",
    );
    s.vtext(16.0, (y0 + y1) / 2.0, LABEL, "density");
    for (i, &d) in dens.iter().enumerate() {
        if d > 0.0 {
            let (a, b) = (xs.at(i as f64 * bw), xs.at((i + 1) as f64 * bw));
            s.rect_tip(
                a,
                ys.at(d),
                (b - a - 0.6).max(0.5),
                y1 - ys.at(d),
                "fill=\"#b9c7d6\" stroke=\"none\" class=\"hist\"",
                &format!(
                    "{} – {} m: {} pairs",
                    val(i as f64 * bw),
                    val((i + 1) as f64 * bw),
                    hist[i]
                ),
            );
        }
    }
    for (i, b) in bands.iter().enumerate() {
        let pts: Vec<(f64, f64)> = grid
            .iter()
            .map(|&x| {
                (
                    xs.at(x),
                    ys.at(b.weight * normal_pdf(x, b.mean_m, b.std_m)).max(y0),
                )
            })
            .collect();
        s.polyline(
            &pts,
            &format!(
                "stroke=\"{}\" stroke-width=\"1.4\" class=\"component\"",
                band_colour(i, k)
            ),
        );
    }
    let pts: Vec<(f64, f64)> = grid
        .iter()
        .zip(&mix_v)
        .map(|(&x, &v)| (xs.at(x), ys.at(v).max(y0)))
        .collect();
    s.polyline(
        &pts,
        "stroke=\"#111111\" stroke-width=\"1.8\" class=\"mixture\"",
    );
    for &bd in sv
        .boundaries_m
        .iter()
        .filter(|b| b.is_finite() && **b > 0.0 && **b < xmax)
    {
        let x = xs.at(bd);
        s.line(
            x,
            y0,
            x,
            y1,
            "stroke=\"#555555\" stroke-width=\"1\" stroke-dasharray=\"3 3\" class=\"boundary\"",
        );
    }
    // BIC panel.
    let (bx0, bx1) = (680.0, 900.0);
    s.text(bx0, 16.0, "start", HEAD, "BIC over k (lower is better)");
    s.rect(
        bx0,
        y0,
        bx1 - bx0,
        y1 - y0,
        "fill=\"#ffffff\" stroke=\"#c8c8c8\"",
    );
    let bic: Vec<_> = sv.bic.iter().filter(|r| r.min.is_finite()).collect();
    let mut bic_desc = String::from("no BIC study");
    if bic.is_empty() {
        s.text(
            (bx0 + bx1) / 2.0,
            (y0 + y1) / 2.0,
            "middle",
            LABEL,
            "no BIC study recorded",
        );
    } else {
        let (lo, hi) = bic
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
                (a.min(r.min), b.max(r.min))
            });
        let (bt, bstep) = ticks(lo, hi, 4);
        let bys = Scale::new(bt[0], bt[bt.len() - 1], y1, y0);
        let kmax = bic.len();
        let bxs = |i: usize| bx0 + (i as f64 + 0.5) / kmax as f64 * (bx1 - bx0);
        for &t in &bt {
            let y = bys.at(t);
            s.line(bx0, y, bx1, y, GRID);
            s.text(bx1 + 3.0, y + 3.5, "start", SMALL, &tick_label(t, bstep));
        }
        let pts: Vec<(f64, f64)> = bic
            .iter()
            .enumerate()
            .map(|(i, r)| (bxs(i), bys.at(r.min)))
            .collect();
        s.polyline(
            &pts,
            "stroke=\"#1f4e79\" stroke-width=\"1.8\" class=\"bic\"",
        );
        for (i, r) in bic.iter().enumerate() {
            let chosen = sv.chosen_k == Some(r.k);
            s.dot(
                bxs(i),
                bys.at(r.min),
                if chosen { 5.5 } else { 3.0 },
                if chosen {
                    "fill=\"#c0392b\" stroke=\"#7b1f16\""
                } else {
                    "fill=\"#1f4e79\""
                },
                &format!(
                    "k = {}: min BIC {}, chosen by {} restart seed(s){}",
                    r.k,
                    fixed(r.min, 1),
                    r.chosen_count,
                    r.gain.map_or(String::new(), |g| format!(
                        ", gain from k−1 {}",
                        fixed(g, 1)
                    ))
                ),
            );
            s.text(bxs(i), y1 + 15.0, "middle", SMALL, &r.k.to_string());
        }
        s.text(
            (bx0 + bx1) / 2.0,
            y1 + 32.0,
            "middle",
            LABEL,
            "number of components k",
        );
        if let Some(ck) = sv.chosen_k
            && let Some(i) = bic.iter().position(|r| r.k == ck)
        {
            let seeds = sv.chosen_per_seed.len();
            let label = if sv.bands_mode == "fixed" {
                format!("k fixed at {ck}")
            } else {
                format!("chosen k = {ck} ({} of {seeds} seeds)", bic[i].chosen_count)
            };
            s.text(
                (bx0 + bx1) / 2.0,
                y0 + 14.0,
                "middle",
                "fill=\"#7b1f16\" font-size=\"10.5\" font-weight=\"bold\"",
                &label,
            );
            bic_desc = label;
        }
    }
    let desc = format!(
        "{} bands: {}. Boundaries at {} m. BIC: {}.",
        k,
        bands
            .iter()
            .map(|b| format!(
                "{} mean {} m, share {}",
                b.name,
                val(b.mean_m),
                pct(b.share)
            ))
            .collect::<Vec<_>>()
            .join("; "),
        if sv.boundaries_m.is_empty() {
            "none".to_string()
        } else {
            sv.boundaries_m
                .iter()
                .map(|b| val(*b))
                .collect::<Vec<_>>()
                .join(", ")
        },
        bic_desc
    );
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes,
    }
}

/// Figure 2b: the action transition matrix of changed pairs as a heat map.
pub(crate) fn transitions(cx: &Ctx) -> Figure {
    const ID: &str = "fig-2b";
    const LABEL_: &str = "Figure 2b";
    let title = "Action transitions of changed pairs";
    let tr = &cx.env.transitions;
    let caption = format!(
        "Action of the clean CoC (rows) against the action of the perturbed CoC (columns) for the {} changed pairs \
         of classified scenarios; cell colour is the row share, the number is the count; the right column gives \
         the share that keeps its action (diagonal, outlined). Overall diagonal share: {}.",
        tr.n,
        crate::draw::opct(tr.diagonal_share)
    );
    let used: Vec<usize> = (0..tr.labels.len())
        .filter(|&i| tr.counts[i].iter().sum::<usize>() > 0 || tr.counts.iter().any(|r| r[i] > 0))
        .collect();
    if tr.n == 0 || used.is_empty() {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            "no changed pairs in the classified scenarios, so there are no action transitions to show.".into(),
        );
    }
    let m = used.len();
    let cell = 44.0f64.min(520.0 / m as f64).max(26.0);
    let lab = used
        .iter()
        .map(|&i| text_w(&tr.labels[i], 10.0))
        .fold(0.0, f64::max);
    let (lx, ty) = ((lab + 34.0).max(90.0), 96.0);
    let w = lx + m as f64 * cell + 90.0;
    let h = ty + m as f64 * cell + 36.0;
    let mut s = Svg::open(ID, w, h, &format!("Figure 2b: {title}"));
    s.text(
        lx + m as f64 * cell / 2.0,
        14.0,
        "middle",
        LABEL,
        "perturbed action",
    );
    s.vtext(14.0, ty + m as f64 * cell / 2.0, LABEL, "clean action");
    for (j, &cj) in used.iter().enumerate() {
        let x = lx + (j as f64 + 0.5) * cell;
        let _ = cj;
        s.raw(&format!(
            "<text x=\"{}\" y=\"{}\" text-anchor=\"start\" transform=\"rotate(-55 {} {})\" {SMALL}>{}</text>\n",
            c(x),
            c(ty - 6.0),
            c(x),
            c(ty - 6.0),
            esc(&tr.labels[cj])
        ));
    }
    s.text(
        lx + m as f64 * cell + 45.0,
        ty - 8.0,
        "middle",
        SMALL,
        "kept",
    );
    let mut desc = String::new();
    for (i, &ri) in used.iter().enumerate() {
        let y = ty + i as f64 * cell;
        let row_n: usize = tr.counts[ri].iter().sum();
        s.text(lx - 6.0, y + cell / 2.0 + 3.5, "end", SMALL, &tr.labels[ri]);
        for (j, &cj) in used.iter().enumerate() {
            let x = lx + j as f64 * cell;
            let n = tr.counts[ri][cj];
            let share = if row_n > 0 {
                n as f64 / row_n as f64
            } else {
                0.0
            };
            let rgb = ramp(&BLUES, share);
            s.rect_tip(
                x,
                y,
                cell,
                cell,
                &format!(
                    "fill=\"{}\" stroke=\"#ffffff\" stroke-width=\"1\" class=\"cell\"",
                    hex(rgb)
                ),
                &format!(
                    "{} → {}: {} pairs ({} of the row)",
                    tr.labels[ri],
                    tr.labels[cj],
                    n,
                    pct(share)
                ),
            );
            if n > 0 {
                s.text(
                    x + cell / 2.0,
                    y + cell / 2.0 + 3.5,
                    "middle",
                    &format!("fill=\"{}\" font-size=\"10\"", ink_on(rgb)),
                    &n.to_string(),
                );
            }
            if ri == cj {
                s.rect(
                    x + 1.0,
                    y + 1.0,
                    cell - 2.0,
                    cell - 2.0,
                    "fill=\"none\" stroke=\"#c0392b\" stroke-width=\"1.5\"",
                );
            }
        }
        let diag = tr.by_action.get(ri).and_then(|a| a.diagonal_share);
        s.text(
            lx + m as f64 * cell + 45.0,
            y + cell / 2.0 + 3.5,
            "middle",
            SMALL,
            &crate::draw::opct(diag),
        );
        let _ = write!(
            desc,
            "{}: {} pairs, {} kept. ",
            tr.labels[ri],
            row_n,
            crate::draw::opct(diag)
        );
    }
    let mut notes = Vec::new();
    if used.len() < tr.labels.len() {
        notes.push(format!(
            "Actions that occur in no changed pair are left out: {}.",
            (0..tr.labels.len())
                .filter(|i| !used.contains(i))
                .map(|i| tr.labels[i].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes,
    }
}

/// Figure 3: joint scenario × band stacked bars, and the high-severity share per scenario
/// coloured by threshold group.
pub(crate) fn joint(cx: &Ctx) -> Figure {
    const ID: &str = "fig-3";
    const LABEL_: &str = "Figure 3";
    let title = "Joint scenario × severity distribution";
    let j = &cx.env.joint;
    let hn = cx.high_name();
    let caption = format!(
        "Left: share of each classified scenario's changed-CoC pairs in bands {} (n at the right). Right: \
         P({hn} | changed) per scenario; bar colour is the threshold group against the all-clips aggregate \
         (red tighter, blue matches, green looser). Dashed: the corpus-wide share; dotted: {}× it (the severe line).",
        if j.bands.is_empty() {
            "—".to_string()
        } else {
            format!("{} to {}", j.bands[0], j.bands[j.bands.len() - 1])
        },
        fixed(cx.severe_factor(), 1)
    );
    if j.bands.is_empty() || j.scenarios.is_empty() {
        let why = if j.bands.is_empty() {
            format!(
                "there are no severity bands ({}), so changed pairs cannot be split by severity.",
                cx.env
                    .severity
                    .reason
                    .clone()
                    .unwrap_or_else(|| "the mixture is undefined".into())
            )
        } else {
            "no classified scenarios.".to_string()
        };
        return Figure::missing(ID, LABEL_, title, caption, why);
    }
    let k = j.bands.len();
    let rows = j.scenarios.len();
    let row_h = 24.0;
    let lab = j
        .scenarios
        .iter()
        .map(|sc| text_w(sc, 11.0))
        .fold(0.0, f64::max);
    let lx = (lab + 18.0).max(110.0);
    let (bx0, bx1) = (lx + 4.0, lx + 340.0);
    let rlab = j
        .scenarios
        .iter()
        .map(|sc| text_w(sc, 10.0))
        .fold(0.0, f64::max);
    let rx0 = bx1 + 64.0 + rlab;
    let rx1 = rx0 + 250.0;
    let ty = 44.0;
    let h = ty + rows as f64 * row_h + 70.0;
    let w = rx1 + 90.0;
    let mut s = Svg::open(ID, w, h, &format!("Figure 3: {title}"));
    s.text(bx0, 16.0, "start", HEAD, "Share of changed pairs per band");
    s.text(
        rx0 - rlab - 6.0,
        16.0,
        "start",
        HEAD,
        &format!("P({hn} | changed)"),
    );
    let mut notes = Vec::new();
    let mut desc = String::new();
    let high_defined = !cx.env.high_severity.bands.is_empty();
    let p_all = cx.p_high_all();
    let mut pmax = p_all.map_or(0.0, |p| p * cx.severe_factor());
    for sc in &j.scenarios {
        if let Some(p) = cx.odd(sc).and_then(|o| o.p_high) {
            pmax = pmax.max(p);
        }
    }
    let (pt, pstep) = ticks(0.0, (pmax * 1.08).max(0.01), 4);
    let rs = Scale::new(0.0, pt[pt.len() - 1], rx0, rx1);
    let yb = ty + rows as f64 * row_h;
    if high_defined {
        for &t in &pt {
            let x = rs.at(t);
            s.line(x, ty - 2.0, x, yb, GRID);
        }
    }
    for (i, sc) in j.scenarios.iter().enumerate() {
        let y = ty + i as f64 * row_h;
        let counts = &j.counts[i];
        let n: usize = counts.iter().sum();
        let pilot = cx.pilot(sc);
        s.text(
            lx - 4.0,
            y + row_h / 2.0 + 3.5,
            "end",
            LABEL,
            &format!("{sc}{}", if pilot { "*" } else { "" }),
        );
        if n == 0 {
            s.rect(
                bx0,
                y + 3.0,
                bx1 - bx0,
                row_h - 6.0,
                "fill=\"#f4f4f4\" stroke=\"#cccccc\" stroke-dasharray=\"3 2\"",
            );
            s.text(
                (bx0 + bx1) / 2.0,
                y + row_h / 2.0 + 3.5,
                "middle",
                SMALL,
                "no changed pairs",
            );
            notes.push(format!(
                "{sc} has no changed-CoC pairs: its severity profile and P({hn}) are undefined."
            ));
            let _ = write!(desc, "{sc}: no changed pairs. ");
        } else {
            let mut x = bx0;
            let mut parts = Vec::new();
            for (b, &cnt) in counts.iter().enumerate() {
                let share = cnt as f64 / n as f64;
                let wd = share * (bx1 - bx0);
                if cnt > 0 {
                    s.rect_tip(
                        x,
                        y + 3.0,
                        wd,
                        row_h - 6.0,
                        &format!(
                            "fill=\"{}\" stroke=\"#ffffff\" stroke-width=\"0.6\" class=\"seg\"",
                            band_colour(b, k)
                        ),
                        &format!(
                            "{sc}, {}: {} of {} changed pairs ({})",
                            j.bands[b],
                            cnt,
                            n,
                            pct(share)
                        ),
                    );
                    if wd > 30.0 {
                        let rgb = ramp(
                            &crate::draw::SEVERITY,
                            if k <= 1 {
                                0.0
                            } else {
                                b as f64 / (k - 1) as f64
                            },
                        );
                        s.text(
                            x + wd / 2.0,
                            y + row_h / 2.0 + 3.5,
                            "middle",
                            &format!("fill=\"{}\" font-size=\"9.5\"", ink_on(rgb)),
                            &fixed(100.0 * share, 0),
                        );
                    }
                }
                parts.push(format!("{} {}", j.bands[b], pct(share)));
                x += wd;
            }
            let _ = write!(desc, "{sc} (n = {n}): {}. ", parts.join(", "));
        }
        s.text(
            bx1 + 6.0,
            y + row_h / 2.0 + 3.5,
            "start",
            SMALL,
            &format!("n = {n}"),
        );
        // Right panel.
        let o = cx.odd(sc);
        s.text(rx0 - 6.0, y + row_h / 2.0 + 3.5, "end", SMALL, sc);
        let group = o.map_or("undefined", |o| o.threshold_group.as_str());
        match (high_defined, o.and_then(|o| o.p_high)) {
            (true, Some(p)) => {
                let x1 = rs.at(p);
                s.rect_tip(
                    rx0,
                    y + 4.0,
                    x1 - rx0,
                    row_h - 8.0,
                    &format!("fill=\"{}\" class=\"high\"", group_colour(group)),
                    &format!(
                        "{sc}: P({hn} | changed) = {}; threshold {group}{}",
                        pct(p),
                        if pilot { " (pilot)" } else { "" }
                    ),
                );
                s.text(
                    x1 + 4.0,
                    y + row_h / 2.0 + 3.5,
                    "start",
                    SMALL,
                    &format!("{} · {group}", pct(p)),
                );
                let _ = write!(desc, "P({hn}) {}, threshold {group}. ", pct(p));
            }
            _ => {
                s.text(
                    rx0 + 4.0,
                    y + row_h / 2.0 + 3.5,
                    "start",
                    SMALL,
                    "undefined",
                );
            }
        }
    }
    // Right-panel axis.
    if high_defined {
        for &t in &pt {
            let x = rs.at(t);
            s.text(
                x,
                yb + 14.0,
                "middle",
                SMALL,
                &format!("{}%", tick_label(100.0 * t, 100.0 * pstep)),
            );
        }
        if let Some(p) = p_all {
            s.line(
                rs.at(p),
                ty - 6.0,
                rs.at(p),
                yb,
                "stroke=\"#333333\" stroke-dasharray=\"4 3\" class=\"p-all\"",
            );
            let sev = p * cx.severe_factor();
            s.line(
                rs.at(sev),
                ty - 6.0,
                rs.at(sev),
                yb,
                "stroke=\"#333333\" stroke-dasharray=\"1 2\"",
            );
            s.text(
                rs.at(p),
                ty - 9.0,
                "middle",
                SMALL,
                &format!("all {}", pct(p)),
            );
        }
    } else {
        notes.push(format!(
            "P(high | changed) is undefined: with {} band(s) no band can be called high severity.",
            k
        ));
    }
    // Bar axis.
    for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let x = bx0 + t * (bx1 - bx0);
        s.line(x, yb, x, yb + 4.0, AXIS);
        s.text(
            x,
            yb + 14.0,
            "middle",
            SMALL,
            &format!("{}%", fixed(100.0 * t, 0)),
        );
    }
    // Legend.
    let ly = yb + 34.0;
    let mut lx2 = bx0;
    for (b, name) in j.bands.iter().enumerate() {
        s.rect(
            lx2,
            ly - 8.0,
            12.0,
            10.0,
            &format!("fill=\"{}\"", band_colour(b, k)),
        );
        s.text(lx2 + 15.0, ly + 1.0, "start", SMALL, name);
        lx2 += 44.0;
    }
    let mut lx3 = rx0 - rlab - 6.0;
    for (g, label) in [
        ("tight", "tighter"),
        ("match", "matches"),
        ("loose", "looser"),
    ] {
        s.rect(
            lx3,
            ly - 8.0,
            12.0,
            10.0,
            &format!("fill=\"{}\"", group_colour(g)),
        );
        s.text(lx3 + 15.0, ly + 1.0, "start", SMALL, label);
        lx3 += 70.0;
    }
    if j.scenarios.iter().any(|sc| cx.pilot(sc)) {
        s.text(
            bx0,
            ly + 20.0,
            "start",
            SMALL,
            "* pilot (few clips): estimates are indicative only",
        );
    }
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes,
    }
}

/// Figure 4: the scenario × condition ΔADE heat map.
pub(crate) fn delta_map(cx: &Ctx) -> Figure {
    const ID: &str = "fig-4";
    const LABEL_: &str = "Figure 4";
    let title = "Scenario × condition ΔADE";
    let caption = "Mean ΔADE (perturbed − clean ADE, m) of every scenario label and the aggregates under every \
                   condition; blue: the perturbation lowered the error, red: raised it (colour symmetric around 0, \
                   scaled to the largest |ΔADE|). * pilot."
        .to_string();
    let conds: Vec<&str> = cx
        .env
        .corpus
        .conditions
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let mut rows: Vec<&str> = Vec::new();
    for m in &cx.env.delta_ade_map {
        if !rows.contains(&m.scenario.as_str()) {
            rows.push(&m.scenario);
        }
    }
    if conds.is_empty() || rows.is_empty() {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            "the envelope has no scenario × condition cells".into(),
        );
    }
    let vmax = cx
        .env
        .delta_ade_map
        .iter()
        .map(|m| m.delta_ade_m.abs())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let lab = rows
        .iter()
        .map(|r| text_w(&Ctx::group_name(r), 10.0))
        .fold(0.0, f64::max);
    let (cw, rh, lx, ty) = (66.0, 24.0, (lab + 20.0).max(120.0), 30.0);
    let w = lx + conds.len() as f64 * cw + 20.0;
    let h = ty + rows.len() as f64 * rh + 60.0;
    let mut s = Svg::open(ID, w, h, &format!("Figure 4: {title}"));
    for (j, cn) in conds.iter().enumerate() {
        s.text(lx + (j as f64 + 0.5) * cw, ty - 8.0, "middle", SMALL, cn);
    }
    let mut desc = String::new();
    for (i, r) in rows.iter().enumerate() {
        let y = ty + i as f64 * rh;
        let name = Ctx::group_name(r);
        let agg = name != *r;
        s.text(
            lx - 6.0,
            y + rh / 2.0 + 3.5,
            "end",
            if agg {
                "fill=\"#111\" font-size=\"10\" font-style=\"italic\""
            } else {
                SMALL
            },
            &format!("{name}{}", if cx.pilot(r) { "*" } else { "" }),
        );
        if agg && i > 0 && !rows[i - 1].starts_with("AGGREGATE") {
            s.line(
                6.0,
                y,
                lx + conds.len() as f64 * cw,
                y,
                "stroke=\"#444\" stroke-width=\"1\"",
            );
        }
        let mut parts = Vec::new();
        for (j, cn) in conds.iter().enumerate() {
            let x = lx + j as f64 * cw;
            let cell = cx
                .env
                .delta_ade_map
                .iter()
                .find(|m| m.scenario == *r && m.condition == *cn);
            match cell.filter(|m| m.delta_ade_m.is_finite() && m.n_pairs > 0) {
                Some(m) => {
                    let t = if vmax > 0.0 {
                        0.5 + 0.5 * m.delta_ade_m / vmax
                    } else {
                        0.5
                    };
                    let rgb = ramp(&DIVERGING, t);
                    s.rect_tip(
                        x,
                        y,
                        cw,
                        rh,
                        &format!(
                            "fill=\"{}\" stroke=\"#ffffff\" stroke-width=\"1\" class=\"cell\"",
                            hex(rgb)
                        ),
                        &format!(
                            "{name} × {cn}: ΔADE {} m over {} pairs",
                            sval(m.delta_ade_m),
                            m.n_pairs
                        ),
                    );
                    s.text(
                        x + cw / 2.0,
                        y + rh / 2.0 + 3.5,
                        "middle",
                        &format!("fill=\"{}\" font-size=\"9.5\"", ink_on(rgb)),
                        &sval(m.delta_ade_m),
                    );
                    parts.push(format!("{cn} {}", sval(m.delta_ade_m)));
                }
                None => {
                    s.rect(x, y, cw, rh, "fill=\"#eeeeee\" stroke=\"#ffffff\"");
                    s.text(x + cw / 2.0, y + rh / 2.0 + 3.5, "middle", SMALL, "—");
                }
            }
        }
        let _ = write!(desc, "{name}: {}. ", parts.join(", "));
    }
    // Colour key.
    let ky = ty + rows.len() as f64 * rh + 22.0;
    let steps = 40;
    let kw = 240.0;
    for i in 0..steps {
        let t = i as f64 / (steps - 1) as f64;
        s.rect(
            lx + t * (kw - kw / steps as f64),
            ky,
            kw / steps as f64 + 0.3,
            10.0,
            &format!("fill=\"{}\"", hex(ramp(&DIVERGING, t))),
        );
    }
    s.text(
        lx,
        ky + 24.0,
        "middle",
        SMALL,
        &format!("{} m", sval(-vmax)),
    );
    s.text(lx + kw / 2.0, ky + 24.0, "middle", SMALL, "0");
    s.text(
        lx + kw,
        ky + 24.0,
        "middle",
        SMALL,
        &format!("{} m", sval(vmax)),
    );
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes: Vec::new(),
    }
}

/// A closed-loop metric: name, scale maximum, accessor, colour.
type Metric = (
    &'static str,
    f64,
    fn(&crate::closed_loop::ClosedLoopRow) -> f64,
    &'static str,
);

/// Figure 5: closed-loop driving score, route completion and infraction score per configuration.
pub(crate) fn closed_loop(cx: &Ctx) -> Figure {
    const ID: &str = "fig-5";
    const LABEL_: &str = "Figure 5";
    let title = "Closed-loop scores per configuration";
    let caption = "Leaderboard-style closed-loop metrics per configuration, averaged over routes: driving score \
                   (0–100), route completion (%), infraction score (penalty product, 0–1)."
        .to_string();
    let Some(cl) = cx.closed_loop else {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            "no closed-loop results were given. Run the closed-loop evaluation and pass its output directory with --sim DIR."
                .into(),
        );
    };
    if cl.configurations.is_empty() {
        return Figure::missing(
            ID,
            LABEL_,
            title,
            caption,
            "the closed-loop results hold no configuration.".into(),
        );
    }
    let rows = cl.configurations.len();
    let row_h = 24.0;
    let lab = cl
        .configurations
        .iter()
        .map(|r| text_w(&format!("{} (n = {})", r.configuration, r.n_routes), 11.0))
        .fold(0.0, f64::max);
    let (lx, pw, gap) = ((lab + 16.0).max(120.0), 230.0, 26.0);
    let ty = 40.0;
    let w = lx + 3.0 * pw + 2.0 * gap + 20.0;
    let h = ty + rows as f64 * row_h + 40.0;
    let mut s = Svg::open(ID, w, h, &format!("Figure 5: {title}"));
    let metrics: [Metric; 3] = [
        ("Driving score", 100.0, |r| r.driving_score, "#1f4e79"),
        (
            "Route completion (%)",
            100.0,
            |r| r.route_completion,
            "#2e8b57",
        ),
        ("Infraction score", 1.0, |r| r.infraction_score, "#b35806"),
    ];
    let mut desc = String::new();
    for (i, r) in cl.configurations.iter().enumerate() {
        let y = ty + i as f64 * row_h;
        s.text(
            lx - 6.0,
            y + row_h / 2.0 + 3.5,
            "end",
            LABEL,
            &format!("{} (n = {})", r.configuration, r.n_routes),
        );
        let _ = write!(
            desc,
            "{}: driving score {}, route completion {}%, infraction score {}. ",
            r.configuration,
            fixed(r.driving_score, 1),
            fixed(r.route_completion, 1),
            fixed(r.infraction_score, 3)
        );
    }
    for (m, (name, max, get, colour)) in metrics.iter().enumerate() {
        let x0 = lx + m as f64 * (pw + gap);
        let x1 = x0 + pw - 50.0;
        s.text(x0, 18.0, "start", HEAD, name);
        let sc = Scale::new(0.0, *max, x0, x1);
        let yb = ty + rows as f64 * row_h;
        for t in [0.0, 0.5, 1.0] {
            let x = sc.at(t * max);
            s.line(x, ty - 2.0, x, yb, GRID);
            s.text(
                x,
                yb + 14.0,
                "middle",
                SMALL,
                &if *max > 1.0 {
                    fixed(t * max, 0)
                } else {
                    fixed(t * max, 1)
                },
            );
        }
        for (i, r) in cl.configurations.iter().enumerate() {
            let y = ty + i as f64 * row_h;
            let v = get(r);
            s.rect_tip(
                x0,
                y + 4.0,
                sc.at(v) - x0,
                row_h - 8.0,
                &format!("fill=\"{colour}\" class=\"bar\""),
                &format!(
                    "{}: {name} {}",
                    r.configuration,
                    if *max > 1.0 { fixed(v, 1) } else { fixed(v, 3) }
                ),
            );
            s.text(
                sc.at(v) + 4.0,
                y + row_h / 2.0 + 3.5,
                "start",
                SMALL,
                &if *max > 1.0 { fixed(v, 1) } else { fixed(v, 3) },
            );
        }
    }
    let svg = s.finish(&desc);
    Figure {
        id: ID,
        label: LABEL_,
        title: title.into(),
        caption,
        svg: Some(svg),
        notes: cl.notes.clone(),
    }
}
