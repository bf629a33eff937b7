//! Drawing and formatting primitives: escaping, fixed-precision numbers, scales, ticks,
//! colours and a small SVG writer. Everything here is deterministic: the same input gives
//! the same bytes.

use std::fmt::Write as _;

/// Escapes text for HTML/SVG element content and attribute values.
pub(crate) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `x` with `prec` decimals; `-0.0…` prints without its sign. Non-finite values print as
/// `—` (the report checks its inputs, so this is a last line of defence, never `NaN`).
pub(crate) fn fixed(x: f64, prec: usize) -> String {
    if !x.is_finite() {
        return "—".into();
    }
    let s = format!("{x:.prec$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// An SVG coordinate: one decimal.
pub(crate) fn c(x: f64) -> String {
    fixed(x, 1)
}

/// A measured value (metres, scores) with a precision that suits its magnitude: three
/// significant digits below 1, three decimals up to 100, one beyond.
pub(crate) fn val(x: f64) -> String {
    let a = x.abs();
    if a >= 100.0 {
        fixed(x, 1)
    } else if a >= 1.0 || a == 0.0 {
        fixed(x, 3)
    } else {
        let decimals = (2 - a.log10().floor() as i32).clamp(3, 8) as usize;
        fixed(x, decimals)
    }
}

/// A signed measured value.
pub(crate) fn sval(x: f64) -> String {
    let v = val(x);
    if x > 0.0 && v.chars().any(|c| c.is_ascii_digit() && c != '0') {
        format!("+{v}")
    } else {
        v
    }
}

/// A share as a percentage with one decimal.
pub(crate) fn pct(x: f64) -> String {
    format!("{}%", fixed(100.0 * x, 1))
}

/// An optional share.
pub(crate) fn opct(x: Option<f64>) -> String {
    x.map_or("—".into(), pct)
}

/// A grid level as written (shortest round-trip form: `10`, `0.3`, `1.6`).
pub(crate) fn level(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        "—".into()
    }
}

/// A threshold: the level, or `none`.
pub(crate) fn olevel(x: Option<f64>) -> String {
    x.map_or("none".into(), level)
}

/// A p-value.
pub(crate) fn pval(p: f64) -> String {
    if !p.is_finite() {
        "—".into()
    } else if p == 0.0 {
        "< 1e-300".into()
    } else if p < 1e-3 {
        format!("{p:.2e}")
    } else {
        fixed(p, 4)
    }
}

/// A linear map from a data interval to a pixel interval.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scale {
    d0: f64,
    d1: f64,
    r0: f64,
    r1: f64,
}

impl Scale {
    /// `[d0, d1] → [r0, r1]`; a zero-width domain is widened so the map stays finite.
    pub(crate) fn new(d0: f64, d1: f64, r0: f64, r1: f64) -> Self {
        let (d0, d1) = if (d1 - d0).abs() < 1e-12 {
            (d0 - 0.5, d1 + 0.5)
        } else {
            (d0, d1)
        };
        Self { d0, d1, r0, r1 }
    }

    /// Maps a value (clamped far outside to keep coordinates sane).
    pub(crate) fn at(&self, x: f64) -> f64 {
        let t = ((x - self.d0) / (self.d1 - self.d0)).clamp(-1.0, 2.0);
        self.r0 + t * (self.r1 - self.r0)
    }
}

/// About `n` round tick values covering `[lo, hi]`, and the step between them.
pub(crate) fn ticks(lo: f64, hi: f64, n: usize) -> (Vec<f64>, f64) {
    let (lo, hi) = if hi - lo < 1e-12 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo, hi)
    };
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).floor() as i64;
    let last = (hi / step).ceil() as i64;
    let v = (first..=last).map(|i| i as f64 * step).collect();
    (v, step)
}

/// A tick label with as many decimals as the step needs.
pub(crate) fn tick_label(x: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-(step.log10().floor()) as usize
            + usize::from((step / 10f64.powf(step.log10().floor()) - 2.5).abs() < 1e-9))
        .min(8)
    };
    fixed(x, decimals)
}

/// Approximate width (user units) of `s` in a sans-serif font of `size`.
pub(crate) fn text_w(s: &str, size: f64) -> f64 {
    s.chars().count() as f64 * size * 0.62
}

/// `#rrggbb` of an RGB triple.
pub(crate) fn hex(rgb: [f64; 3]) -> String {
    let q = |v: f64| v.round().clamp(0.0, 255.0) as u8;
    format!("#{:02x}{:02x}{:02x}", q(rgb[0]), q(rgb[1]), q(rgb[2]))
}

fn lerp3(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Piecewise-linear colour ramp through `stops` at `t` in [0, 1].
pub(crate) fn ramp(stops: &[[f64; 3]], t: f64) -> [f64; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let n = stops.len() - 1;
    let x = t * n as f64;
    let i = (x.floor() as usize).min(n - 1);
    lerp3(stops[i], stops[i + 1], x - i as f64)
}

/// Sequential ramp for counts and shares: white to deep blue.
pub(crate) const BLUES: [[f64; 3]; 4] = [
    [247.0, 251.0, 255.0],
    [198.0, 219.0, 239.0],
    [66.0, 146.0, 198.0],
    [8.0, 48.0, 107.0],
];

/// Diverging ramp for signed values: blue, white, red.
pub(crate) const DIVERGING: [[f64; 3]; 5] = [
    [33.0, 102.0, 172.0],
    [146.0, 197.0, 222.0],
    [247.0, 247.0, 247.0],
    [244.0, 165.0, 130.0],
    [178.0, 24.0, 43.0],
];

/// Severity ramp for bands: pale yellow to dark red.
pub(crate) const SEVERITY: [[f64; 3]; 5] = [
    [255.0, 237.0, 160.0],
    [254.0, 178.0, 76.0],
    [252.0, 78.0, 42.0],
    [189.0, 0.0, 38.0],
    [100.0, 0.0, 30.0],
];

/// Colour of band `i` of `k`.
pub(crate) fn band_colour(i: usize, k: usize) -> String {
    let t = if k <= 1 {
        0.0
    } else {
        i as f64 / (k - 1) as f64
    };
    hex(ramp(&SEVERITY, t))
}

/// Text colour that reads on a fill of the given RGB.
pub(crate) fn ink_on(rgb: [f64; 3]) -> &'static str {
    let lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
    if lum < 140.0 { "#ffffff" } else { "#1a1a1a" }
}

/// Colour of a threshold group (as in the paper's figure 3: red tighter, blue matches,
/// green looser; grey when undefined).
pub(crate) fn group_colour(group: &str) -> &'static str {
    match group {
        "tight" | "tighter" => "#c0392b",
        "match" | "matches" => "#2c6fbb",
        "loose" | "looser" => "#2e8b57",
        _ => "#8c8c8c",
    }
}

/// A small SVG writer with the accessibility boilerplate.
pub(crate) struct Svg {
    head: String,
    id: String,
    buf: String,
}

impl Svg {
    /// Opens `<svg>` of `w × h` user units with `role="img"` and a `<title>`; the `<desc>`
    /// is given to [`Svg::finish`], once the drawing knows what it shows.
    pub(crate) fn open(id: &str, w: f64, h: f64, title: &str) -> Self {
        let mut head = String::new();
        let _ = write!(
            head,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" id=\"{id}-svg\" class=\"chart\" viewBox=\"0 0 {} {}\" width=\"{}\" height=\"{}\" role=\"img\" aria-labelledby=\"{id}-title {id}-desc\" font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\" font-size=\"11\">\n<title id=\"{id}-title\">{}</title>\n",
            c(w),
            c(h),
            c(w),
            c(h),
            esc(title),
        );
        Self {
            head,
            id: id.to_string(),
            buf: String::with_capacity(16 * 1024),
        }
    }

    /// Raw markup.
    pub(crate) fn raw(&mut self, s: &str) {
        self.buf.push_str(s);
    }

    /// A line.
    pub(crate) fn line(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, style: &str) {
        let _ = writeln!(
            self.buf,
            "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" {style}/>",
            c(x1),
            c(y1),
            c(x2),
            c(y2)
        );
    }

    /// A rectangle.
    pub(crate) fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, style: &str) {
        let _ = writeln!(
            self.buf,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" {style}/>",
            c(x),
            c(y),
            c(w.max(0.0)),
            c(h.max(0.0))
        );
    }

    /// A rectangle with a tooltip.
    pub(crate) fn rect_tip(&mut self, x: f64, y: f64, w: f64, h: f64, style: &str, tip: &str) {
        let _ = writeln!(
            self.buf,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" {style}><title>{}</title></rect>",
            c(x),
            c(y),
            c(w.max(0.0)),
            c(h.max(0.0)),
            esc(tip)
        );
    }

    /// Text (escaped); `anchor` is `start`, `middle` or `end`.
    pub(crate) fn text(&mut self, x: f64, y: f64, anchor: &str, style: &str, s: &str) {
        let _ = writeln!(
            self.buf,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"{anchor}\" {style}>{}</text>",
            c(x),
            c(y),
            esc(s)
        );
    }

    /// Text rotated by −90° about its anchor point.
    pub(crate) fn vtext(&mut self, x: f64, y: f64, style: &str, s: &str) {
        let _ = writeln!(
            self.buf,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 {} {})\" {style}>{}</text>",
            c(x),
            c(y),
            c(x),
            c(y),
            esc(s)
        );
    }

    /// A polyline through points.
    pub(crate) fn polyline(&mut self, pts: &[(f64, f64)], style: &str) {
        if pts.is_empty() {
            return;
        }
        let mut p = String::new();
        for (i, (x, y)) in pts.iter().enumerate() {
            if i > 0 {
                p.push(' ');
            }
            let _ = write!(p, "{},{}", c(*x), c(*y));
        }
        let _ = writeln!(self.buf, "<polyline points=\"{p}\" fill=\"none\" {style}/>");
    }

    /// A closed polygon.
    pub(crate) fn polygon(&mut self, pts: &[(f64, f64)], style: &str) {
        if pts.len() < 3 {
            return;
        }
        let mut p = String::new();
        for (i, (x, y)) in pts.iter().enumerate() {
            if i > 0 {
                p.push(' ');
            }
            let _ = write!(p, "{},{}", c(*x), c(*y));
        }
        let _ = writeln!(self.buf, "<polygon points=\"{p}\" {style}/>");
    }

    /// A circle with a tooltip.
    pub(crate) fn dot(&mut self, x: f64, y: f64, r: f64, style: &str, tip: &str) {
        let _ = writeln!(
            self.buf,
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" {style}><title>{}</title></circle>",
            c(x),
            c(y),
            c(r),
            esc(tip)
        );
    }

    /// Closes the element with its long description and returns the markup.
    pub(crate) fn finish(self, desc: &str) -> String {
        let mut out = self.head;
        let _ = writeln!(
            out,
            "<desc id=\"{}-desc\">{}</desc>",
            self.id,
            esc(desc.trim_end())
        );
        out.push_str(&self.buf);
        out.push_str("</svg>\n");
        out
    }
}

/// Axis tick and grid styles.
pub(crate) const AXIS: &str = "stroke=\"#444\" stroke-width=\"1\"";
/// Light grid lines.
pub(crate) const GRID: &str = "stroke=\"#e3e3e3\" stroke-width=\"1\"";
/// Small grey text.
pub(crate) const SMALL: &str = "fill=\"#444\" font-size=\"10\"";
/// Axis titles.
pub(crate) const LABEL: &str = "fill=\"#222\" font-size=\"11\"";
/// Panel titles.
pub(crate) const HEAD: &str = "fill=\"#111\" font-size=\"12\" font-weight=\"bold\"";

/// Draws a left y axis with ticks and grid over `[x0, x1]`, and returns the tick step.
pub(crate) fn y_axis(s: &mut Svg, sc: &Scale, ticks_v: &[f64], step: f64, x0: f64, x1: f64) {
    for &t in ticks_v {
        let y = sc.at(t);
        s.line(x0, y, x1, y, GRID);
        s.line(x0 - 4.0, y, x0, y, AXIS);
        s.text(x0 - 6.0, y + 3.5, "end", SMALL, &tick_label(t, step));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_never_prints_negative_zero_or_nan() {
        assert_eq!(fixed(-0.00001, 2), "0.00");
        assert_eq!(fixed(-0.5, 1), "-0.5");
        assert_eq!(fixed(f64::NAN, 2), "—");
        assert_eq!(fixed(f64::INFINITY, 2), "—");
    }

    #[test]
    fn values_keep_three_significant_digits() {
        assert_eq!(val(0.000476), "0.000476");
        assert_eq!(val(0.0123), "0.0123");
        assert_eq!(val(0.5), "0.500");
        assert_eq!(val(12.3456), "12.346");
        assert_eq!(val(123.45), "123.5");
        assert_eq!(val(0.0), "0.000");
        assert_eq!(sval(0.25), "+0.250");
        assert_eq!(sval(-0.25), "-0.250");
        assert_eq!(sval(0.0), "0.000");
    }

    #[test]
    fn ticks_cover_the_range_with_round_steps() {
        let (t, step) = ticks(0.0, 70.0, 5);
        assert_eq!(step, 20.0);
        assert_eq!(t.first().copied(), Some(0.0));
        assert!(t.last().copied().unwrap_or(0.0) >= 70.0);
        let (t, step) = ticks(-0.013, 0.41, 5);
        assert!(step > 0.0 && t[0] <= -0.013 && *t.last().unwrap_or(&0.0) >= 0.41);
        assert_eq!(tick_label(0.25, 0.25), "0.25");
        assert_eq!(tick_label(0.2, 0.1), "0.2");
        assert_eq!(tick_label(40.0, 20.0), "40");
        let (t, _) = ticks(3.0, 3.0, 4);
        assert!(t.len() >= 2);
    }

    #[test]
    fn escaping_covers_markup_characters() {
        assert_eq!(
            esc("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
    }

    #[test]
    fn ramps_stay_in_gamut() {
        assert_eq!(hex(ramp(&BLUES, 0.0)), "#f7fbff");
        assert_eq!(hex(ramp(&BLUES, 1.0)), "#08306b");
        assert_eq!(hex(ramp(&BLUES, f64::NAN)), "#f7fbff");
        assert_eq!(band_colour(0, 1), band_colour(0, 6));
    }
}
