//! The page in a real browser: Debian's headless Chromium, driven over the DevTools
//! protocol on 127.0.0.1. Checks that the page loads from disk with no console error, no
//! network request and every figure rendered; prints it to PDF; and saves a screenshot to
//! `docs/report-screenshot.png`. Fails (never skips) when the browser is missing.

use std::time::Duration;

use base64::Engine as _;
use fogline_report::{ReportParams, render};
use serde_json::{Value, json};

use crate::cdp::{Browser, chromium_path};
use crate::fixture::{crate_dir, fixture};

const CHECK_FIGURES: &str = r#"(() => {
  const out = [];
  for (const f of document.querySelectorAll('figure.fig')) {
    const svg = f.querySelector('svg');
    const r = svg ? svg.getBoundingClientRect() : null;
    let bbox = null;
    try { if (svg) { const b = svg.getBBox(); bbox = [b.width, b.height]; } } catch (e) { bbox = null; }
    let hit = false;
    if (r && r.width > 0 && r.height > 0) {
      f.scrollIntoView();
      const q = svg.getBoundingClientRect();
      const el = document.elementFromPoint(q.left + q.width / 2, q.top + q.height / 2);
      hit = !!el && (el === svg || svg.contains(el));
    }
    const style = svg ? getComputedStyle(svg) : null;
    const title = svg ? svg.querySelector('title') : null;
    const desc = svg ? svg.querySelector('desc') : null;
    out.push({
      id: f.id,
      drawn: f.dataset.drawn === 'true',
      width: r ? r.width : 0,
      height: r ? r.height : 0,
      bbox: bbox,
      hit: hit,
      visible: style ? (style.display !== 'none' && style.visibility !== 'hidden') : false,
      shapes: svg ? svg.querySelectorAll('rect,line,polyline,polygon,circle,path,text').length : 0,
      role: svg ? svg.getAttribute('role') : null,
      labelled: svg ? (svg.getAttribute('aria-labelledby') || '').split(' ').every(id => !!document.getElementById(id)) : false,
      title: title ? title.textContent : '',
      desc: desc ? desc.textContent.length : 0,
      missing: f.querySelector('.fig-missing') ? f.querySelector('.fig-missing').textContent : null,
    });
  }
  window.scrollTo(0, 0);
  return JSON.stringify({
    figures: out,
    title: document.title,
    tables: document.querySelectorAll('table').length,
    nan: document.body.innerText.includes('NaN'),
    height: document.documentElement.scrollHeight,
  });
})()"#;

#[test]
fn browser_page_loads_offline_renders_every_figure_and_is_screenshotted() {
    let exe = chromium_path();
    assert!(
        exe.exists(),
        "{} is missing: run scripts/browser-deps.sh (installs Debian's chromium), or set FOGLINE_CHROMIUM",
        exe.display()
    );
    let report = render(&fixture(), &ReportParams::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("report.html");
    std::fs::write(&page, &report.html).unwrap();
    let url = format!("file://{}", page.display());

    let mut b = Browser::launch(&exe).unwrap();
    let target = b
        .call(None, "Target.createTarget", json!({"url": "about:blank"}))
        .unwrap();
    let target_id = target["targetId"].as_str().unwrap().to_string();
    let attached = b
        .call(
            None,
            "Target.attachToTarget",
            json!({"targetId": target_id, "flatten": true}),
        )
        .unwrap();
    let sid = attached["sessionId"].as_str().unwrap().to_string();
    let s = Some(sid.as_str());
    for m in [
        "Runtime.enable",
        "Log.enable",
        "Network.enable",
        "Page.enable",
    ] {
        b.call(s, m, json!({})).unwrap();
    }
    b.call(
        s,
        "Emulation.setDeviceMetricsOverride",
        json!({"width": 1280, "height": 1500, "deviceScaleFactor": 1, "mobile": false}),
    )
    .unwrap();
    b.events.clear();
    b.call(s, "Page.navigate", json!({"url": url})).unwrap();
    b.wait_event("Page.loadEventFired", Duration::from_secs(60))
        .unwrap();
    b.drain(Duration::from_millis(800));

    // Figures.
    let res = b
        .call(
            s,
            "Runtime.evaluate",
            json!({"expression": CHECK_FIGURES, "returnByValue": true}),
        )
        .unwrap();
    let v: Value = serde_json::from_str(res["result"]["value"].as_str().unwrap()).unwrap();
    let figs = v["figures"].as_array().unwrap();
    assert_eq!(figs.len(), report.figures.len(), "figures on the page: {v}");
    for (f, want) in figs.iter().zip(&report.figures) {
        assert_eq!(f["id"], want.id.as_str());
        assert_eq!(f["drawn"], want.drawn, "{}", want.id);
        if want.drawn {
            let (w, h) = (f["width"].as_f64().unwrap(), f["height"].as_f64().unwrap());
            assert!(w > 300.0 && h > 100.0, "{} renders at {w} × {h}", want.id);
            let bbox = f["bbox"].as_array().expect("an SVG bounding box");
            assert!(
                bbox.iter().all(|x| x.as_f64().unwrap() > 50.0),
                "{}: empty drawing {bbox:?}",
                want.id
            );
            assert!(
                f["visible"] == true && f["hit"] == true,
                "{} is not visible: {f}",
                want.id
            );
            assert!(
                f["shapes"].as_u64().unwrap() > 20,
                "{} has too few shapes: {f}",
                want.id
            );
            assert!(
                f["role"] == "img" && f["labelled"] == true,
                "{} lacks accessible labels: {f}",
                want.id
            );
            assert!(
                f["desc"].as_u64().unwrap() > 40,
                "{} has no description: {f}",
                want.id
            );
        } else {
            assert!(
                f["missing"]
                    .as_str()
                    .is_some_and(|m| m.starts_with("Not drawn: ")),
                "{f}"
            );
        }
    }
    assert!(v["tables"].as_u64().unwrap() >= 15, "{v}");
    assert_eq!(v["nan"], false);

    // Printing works (A4 PDF) and keeps every figure.
    b.call(s, "Emulation.setEmulatedMedia", json!({"media": "print"}))
        .unwrap();
    let res = b
        .call(
            s,
            "Runtime.evaluate",
            json!({"expression": CHECK_FIGURES, "returnByValue": true}),
        )
        .unwrap();
    let pv: Value = serde_json::from_str(res["result"]["value"].as_str().unwrap()).unwrap();
    for f in pv["figures"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["drawn"] == true)
    {
        assert!(
            f["width"].as_f64().unwrap() > 300.0,
            "printed figure {} collapses: {f}",
            f["id"]
        );
    }
    let pdf = b
        .call(
            s,
            "Page.printToPDF",
            json!({"printBackground": true, "preferCSSPageSize": true}),
        )
        .unwrap();
    let pdf = base64::engine::general_purpose::STANDARD
        .decode(pdf["data"].as_str().unwrap())
        .unwrap();
    assert!(
        pdf.starts_with(b"%PDF") && pdf.len() > 50_000,
        "PDF of {} bytes",
        pdf.len()
    );
    b.call(s, "Emulation.setEmulatedMedia", json!({"media": ""}))
        .unwrap();

    // Screenshot of the top of the page for the docs.
    let shot = b
        .call(
            s,
            "Page.captureScreenshot",
            json!({"format": "png", "captureBeyondViewport": false}),
        )
        .unwrap();
    let png = base64::engine::general_purpose::STANDARD
        .decode(shot["data"].as_str().unwrap())
        .unwrap();
    assert!(png.starts_with(b"\x89PNG") && png.len() > 20_000);
    let docs = crate_dir().join("../../docs/report-screenshot.png");
    std::fs::write(&docs, &png).unwrap();

    b.drain(Duration::from_millis(300));
    // No console errors, no exceptions, no network request but the page itself.
    let mut problems = Vec::new();
    for e in &b.events {
        let p = &e["params"];
        match e["method"].as_str().unwrap_or("") {
            "Runtime.consoleAPICalled"
                if matches!(p["type"].as_str(), Some("error" | "assert" | "warning")) =>
            {
                problems.push(format!("console {}: {}", p["type"], p["args"]))
            }
            "Runtime.exceptionThrown" => {
                problems.push(format!("exception: {}", p["exceptionDetails"]))
            }
            "Log.entryAdded"
                if matches!(p["entry"]["level"].as_str(), Some("error" | "warning")) =>
            {
                problems.push(format!(
                    "log {}: {}",
                    p["entry"]["level"], p["entry"]["text"]
                ))
            }
            "Network.requestWillBeSent" if p["request"]["url"].as_str() != Some(url.as_str()) => {
                problems.push(format!("network request: {}", p["request"]["url"]))
            }
            "Network.loadingFailed" => problems.push(format!("loading failed: {p}")),
            _ => {}
        }
    }
    let page_loads = b
        .events
        .iter()
        .filter(|e| {
            e["method"] == "Network.requestWillBeSent"
                && e["params"]["request"]["url"].as_str() == Some(url.as_str())
        })
        .count();
    assert_eq!(page_loads, 1, "the page itself should be the one request");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    let _ = b.call(None, "Browser.close", json!({}));
}

const CHECK_GALLERY: &str = r#"(() => {
  const imgs = [...document.querySelectorAll('.gallery img')];
  return JSON.stringify({
    images: imgs.length,
    decoded: imgs.filter(i => i.complete && i.naturalWidth > 0).length,
    laid_out: imgs.filter(i => i.getBoundingClientRect().width >= 40).length,
    samples: document.querySelectorAll('figure.sample').length,
    tables: document.querySelectorAll('table').length,
    nan: document.body.innerText.includes('NaN'),
  });
})()"#;

/// The DriveLM-Deficit page: every gallery frame decodes from its data URL and is laid out,
/// with no console error and no request beyond the page and its inline images.
#[test]
fn browser_deficit_page_shows_every_gallery_frame() {
    let exe = chromium_path();
    assert!(exe.exists(), "{} is missing", exe.display());
    let text = std::fs::read_to_string(crate_dir().join("tests/data/deficit_eval.json")).unwrap();
    let e = fogline_report::deficit::deficit_eval_from_json(&text, "deficit_eval.json").unwrap();
    let picks = fogline_report::deficit::pick_gallery(&e, 3);
    let gallery = picks
        .iter()
        .map(|&i| fogline_report::deficit::GallerySample {
            id: e.answers[i].id.clone(),
            expert_rationale: None,
            frames: (0..15)
                .map(|k| {
                    let (camera, w, h) = match k / 5 {
                        0 => ("cross_left", 96, 72),
                        1 => ("front_wide", 192, 144),
                        _ => ("cross_right", 96, 72),
                    };
                    fogline_report::deficit::GalleryFrame {
                        camera: camera.into(),
                        t_s: f64::from(k % 5) - 4.0,
                        width: w,
                        height: h,
                        rgb: vec![(40 * k) as u8; (w * h * 3) as usize],
                    }
                })
                .collect(),
        })
        .collect();
    let d = fogline_report::deficit::DeficitSection::new(e, gallery).unwrap();
    let html = fogline_report::deficit::render_page(&d, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("report.html");
    std::fs::write(&page, &html).unwrap();
    let url = format!("file://{}", page.display());

    let mut b = Browser::launch(&exe).unwrap();
    let target = b
        .call(None, "Target.createTarget", json!({"url": "about:blank"}))
        .unwrap();
    let attached = b
        .call(
            None,
            "Target.attachToTarget",
            json!({"targetId": target["targetId"], "flatten": true}),
        )
        .unwrap();
    let sid = attached["sessionId"].as_str().unwrap().to_string();
    let s = Some(sid.as_str());
    for m in [
        "Runtime.enable",
        "Log.enable",
        "Network.enable",
        "Page.enable",
    ] {
        b.call(s, m, json!({})).unwrap();
    }
    b.events.clear();
    b.call(s, "Page.navigate", json!({"url": url})).unwrap();
    b.wait_event("Page.loadEventFired", Duration::from_secs(60))
        .unwrap();
    b.drain(Duration::from_millis(500));
    let res = b
        .call(
            s,
            "Runtime.evaluate",
            json!({"expression": CHECK_GALLERY, "returnByValue": true}),
        )
        .unwrap();
    let v: Value = serde_json::from_str(res["result"]["value"].as_str().unwrap()).unwrap();
    assert_eq!(v["samples"], 3, "{v}");
    assert_eq!(v["images"], 45, "{v}");
    assert_eq!(v["decoded"], 45, "every frame decodes: {v}");
    assert_eq!(v["laid_out"], 45, "every frame is laid out: {v}");
    assert!(v["tables"].as_u64().unwrap() >= 5 + 3, "{v}");
    assert_eq!(v["nan"], false);
    let mut problems = Vec::new();
    for ev in &b.events {
        let p = &ev["params"];
        match ev["method"].as_str().unwrap_or("") {
            "Runtime.consoleAPICalled" | "Runtime.exceptionThrown" => {
                problems.push(format!("{ev}"))
            }
            "Log.entryAdded"
                if matches!(p["entry"]["level"].as_str(), Some("error" | "warning")) =>
            {
                problems.push(format!("{ev}"))
            }
            "Network.requestWillBeSent" => {
                let u = p["request"]["url"].as_str().unwrap_or("");
                if u != url && !u.starts_with("data:image/png;base64,") {
                    problems.push(format!("network request: {u}"));
                }
            }
            "Network.loadingFailed" => problems.push(format!("loading failed: {p}")),
            _ => {}
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    let _ = b.call(None, "Browser.close", json!({}));
}
