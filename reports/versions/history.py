"""The history page: every metric over engine versions and over successive result folders.

``build_history(folders)`` reads results folders and returns the page's data; ``write_history``
writes ``history.html``: one self-contained file (no network: the data is a JSON block, the
charts are SVG drawn by a short inline script), with

- per engine held in several versions (a ``director-bench versions`` folder): one chart per
  scenario and metric, x = the engine's versions in release order, one line per configuration
  (engine, integrator, dt, target accuracy), the changes between consecutive versions
  (:mod:`reports.versions.changes`) marked with a ring (red worse, green better, amber
  changed) on the chart of the metric that changed (a change of energy behaviour on the
  energy chart; of status, verdict or integrator on the energy and attitude charts);
- with two or more folders (e.g. nightly runs of an engine's main branch): the same charts
  with x = the folders in the order given, changes between consecutive folders marked the same
  way (metric beyond its factor and floor, status, verdict).

Hovering a point names it (configuration, version or folder, value, status); clicking a point,
a line or a legend entry shows only that configuration (charts without it are hidden); the
``show all`` button or a second click brings everything back. Error metrics are drawn on a log
scale, values below a metric's round-off floor at the floor; a run that did not end ``ok`` is a
cross at the top of its chart.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

from reports.gate.rule import classify
from reports.metrics.catalog import FLOORS, HIGHER_IS_BETTER, METRIC_COLUMNS, METRIC_UNITS
from reports.store.results import read_results
from reports.store.runs import CONFIG_KEY, config_key
from reports.versions.changes import COST_COLUMN, _name, load_table
from scenarios.schema import InputError

#: the unit of each column drawn: the metric catalog's, and the cost column's
UNITS = {**METRIC_UNITS, COST_COLUMN: "ns"}


def _metrics() -> list[str]:
    return [m for m in (*METRIC_COLUMNS, COST_COLUMN)]


def _num(v):
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(x) else x


def _cfg_label(key) -> str:
    sc, eng, integ, dt, acc = key
    s = f"{eng} {integ} dt={dt:g}"
    return s + ("" if acc is None else f" acc={acc:g}")


def _charts(points_by_key: dict, xs: list[str], marks: dict) -> list[dict]:
    """Charts of one view. ``points_by_key``: config key -> list over xs of row-or-None;
    ``marks``: (config key, metric) -> list of (x index, direction, text)."""
    charts = []
    scenarios = sorted({k[0] for k in points_by_key})
    for sc in scenarios:
        keys = sorted(
            (k for k in points_by_key if k[0] == sc), key=lambda k: (k[1], k[2], k[3], k[4] or 0)
        )
        for metric in _metrics():
            series = []
            for k in keys:
                pts = []
                for xi, r in enumerate(points_by_key[k]):
                    if r is None or r["status"] in ("unsupported",):
                        continue
                    v = _num(r.get(metric))
                    if r["status"] != "ok" or v is None or math.isinf(v):
                        if r["status"] == "ok":
                            continue  # an ok run without this metric
                        pts.append([xi, None, r["status"], r["engine_version"]])
                    else:
                        pts.append([xi, v, "ok", r["engine_version"]])
                if any(p[1] is not None for p in pts):
                    sid = _name(k)
                    m = [
                        {"x": xi, "direction": d, "text": t}
                        for xi, d, t in marks.get((k, metric), [])
                    ]
                    series.append({"sid": sid, "label": _cfg_label(k), "points": pts, "marks": m})
            if series:
                charts.append(
                    {
                        "scenario": sc,
                        "metric": metric,
                        "unit": UNITS.get(metric, ""),
                        "log": metric not in HIGHER_IS_BETTER,
                        "floor": FLOORS.get(metric, 0.0),
                        "series": series,
                    }
                )
    return charts


def _version_view(folder: Path, factor: float) -> list[dict]:
    tab = load_table(folder, factor)
    views = []
    for eng, versions in tab.versions.items():
        keys = tab.configs(eng)
        pts = {k: [tab.row(k, v) for v in versions] for k in keys}
        marks: dict = {}
        for c in tab.changes:
            if c.engine != eng:
                continue
            xi = versions.index(c.to_version)
            text = f"{c.from_version} -> {c.to_version}: {c.column} {c.direction}"
            cols = {
                "metric": [c.column],
                "cost": [c.column],
                "behaviour": ["energy_drift_max"],
            }.get(
                c.kind, ["energy_drift_max", "attitude_error_max"]
            )  # status, verdict, integrator: on the two charts every scenario has
            targets = (
                [k for k in keys if k == c.key]
                if c.dt is not None
                else [
                    k
                    for k in keys
                    if (k[0], k[2], k[4]) == (c.scenario, c.integrator, c.target_accuracy)
                ]
            )
            for k in targets:
                for col in cols:
                    marks.setdefault((k, col), []).append((xi, c.direction, text))
        views.append(
            {
                "title": f"{eng} over versions ({folder.name})",
                "axis": "version",
                "x": versions,
                "charts": _charts(pts, versions, marks),
            }
        )
    return views


def _folder_label(folder: Path) -> str:
    prov = folder / "provenance.json"
    when = ""
    try:
        doc = json.loads(prov.read_text())
        when = str(doc.get("created") or doc.get("time") or doc.get("date") or "")[:16]
    except (OSError, ValueError):
        pass
    return f"{folder.name}" + (f" ({when})" if when else "")


def _folder_view(folders: list[Path], factor: float) -> dict:
    xs = [_folder_label(f) for f in folders]
    per = []
    for f in folders:
        df = read_results(f)
        per.append({config_key(*(r[c] for c in CONFIG_KEY)): r for r in df.to_dict("records")})
    keys = sorted(set().union(*per), key=lambda k: (k[0], k[1], k[2], k[3], k[4] or 0))
    pts = {k: [p.get(k) for p in per] for k in keys}
    marks: dict = {}
    for k in keys:
        for i in range(1, len(per)):
            a, b = per[i - 1].get(k), per[i].get(k)
            if a is None or b is None:
                continue
            text0 = f"{xs[i - 1]} -> {xs[i]}"
            if a["status"] != b["status"] or a["verdict"] != b["verdict"]:
                for col in ("energy_drift_max", "attitude_error_max"):
                    marks.setdefault((k, col), []).append(
                        (i, "changed", f"{text0}: {a['status']}/{a['verdict']} -> "
                         f"{b['status']}/{b['verdict']}")
                    )  # fmt: skip
                continue
            for col in METRIC_COLUMNS:
                got = classify(col, a.get(col), b.get(col), factor)
                if got and got[1] != "same":
                    marks.setdefault((k, col), []).append((i, got[1], f"{text0}: {col} {got[1]}"))
    return {
        "title": "over result folders",
        "axis": "folder",
        "x": xs,
        "charts": _charts(pts, xs, marks),
    }


def build_history(folders, factor: float = 2.0) -> dict:
    """The page's data (see the module docstring) from one or more results folders."""
    folders = [Path(f) for f in folders]
    if not folders:
        raise InputError("history: no results folder given")
    for f in folders:
        if not (f / "results.sqlite").exists():
            raise FileNotFoundError(f"{f}: no results store here (results.sqlite is missing)")
    views = []
    for f in folders:
        views += [v for v in _version_view(f, factor) if len(v["x"]) > 1]
    if len(folders) > 1:
        views.append(_folder_view(folders, factor))
    if not views:
        views = _version_view(folders[0], factor)
    return {"factor": factor, "views": views}


def write_history(
    folders, path, factor: float = 2.0, title: str = "director-bench history"
) -> Path:
    """Write the self-contained page for ``folders`` to ``path``."""
    data = build_history(folders, factor)
    blob = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    page = (
        _PAGE.replace("__TITLE__", html.escape(title))
        .replace("__DATA__", blob)
        .replace("__SCRIPT__", _SCRIPT)
    )
    path = Path(path)
    path.write_text(page)
    return path


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>
body{font:14px/1.4 system-ui,sans-serif;margin:16px;color:#222;background:#fff}
h1{font-size:20px;margin:0 0 4px} h2{font-size:17px;margin:22px 0 6px}
h3{font-size:14px;margin:14px 0 4px;color:#444}
.grid{display:flex;flex-wrap:wrap;gap:10px}
.chart{border:1px solid #ddd;border-radius:4px;background:#fcfcfc}
.legend{display:flex;flex-wrap:wrap;gap:4px 12px;margin:6px 0;font-size:12px}
.legend span{cursor:pointer;white-space:nowrap} .legend i{display:inline-block;width:14px;
height:3px;margin-right:4px;vertical-align:middle}
.legend span.off{opacity:.3}
#tooltip{position:fixed;pointer-events:none;background:#222;color:#fff;padding:4px 7px;
border-radius:3px;font-size:12px;display:none;max-width:420px;z-index:9}
#bar{position:sticky;top:0;background:#fff;padding:6px 0;border-bottom:1px solid #eee;z-index:5}
button{font:inherit} .note{color:#666;font-size:12px}
.pt,.line{cursor:pointer} .hidden{display:none}
</style></head><body>
<h1>__TITLE__</h1>
<div class="note">Every metric over engine versions and result folders. Hover a point to name
it; click a point, a line or a legend entry to show only that configuration. Rings mark a
change against the previous version or folder: red worse, green better, amber changed. Error
metrics on a log scale, clipped at their round-off floor; a cross at the top is a run that did
not end ok.</div>
<div id="bar"><button id="showall">show all</button> <span id="filter"></span></div>
<div id="views"></div><div id="tooltip"></div>
<script type="application/json" id="data">__DATA__</script>
<script>__SCRIPT__</script>
</body></html>
"""

_SCRIPT = r"""
(function () {
  var data = JSON.parse(document.getElementById('data').textContent);
  var NS = 'http://www.w3.org/2000/svg', W = 430, H = 230, L = 58, R = 10, T = 24, B = 46;
  var tip = document.getElementById('tooltip'), filt = null, colors = {};
  var pal = ['#1f77b4','#d62728','#2ca02c','#9467bd','#ff7f0e','#8c564b','#e377c2','#17becf',
             '#7f7f7f','#bcbd22','#393b79','#637939','#843c39','#7b4173','#3182bd','#e6550d'];
  function color(sid) {
    if (!(sid in colors)) colors[sid] = pal[Object.keys(colors).length % pal.length];
    return colors[sid];
  }
  function el(tag, attrs, parent) {
    var e = document.createElementNS(NS, tag);
    for (var k in attrs) e.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(e);
    return e;
  }
  function fmt(v) { return v === null ? '-' : (Math.abs(v) >= 1e-3 && Math.abs(v) < 1e4 ?
    Number(v.toPrecision(4)).toString() : v.toExponential(2)); }
  function show(evt, text) {
    tip.textContent = text; tip.style.display = 'block';
    tip.style.left = (evt.clientX + 12) + 'px'; tip.style.top = (evt.clientY + 12) + 'px';
  }
  function hide() { tip.style.display = 'none'; }
  function setFilter(sid) {
    filt = (filt === sid) ? null : sid;
    document.getElementById('filter').textContent = filt ? 'showing only: ' + filt : '';
    document.querySelectorAll('[data-sid]').forEach(function (e) {
      var on = !filt || e.getAttribute('data-sid') === filt;
      if (e.tagName === 'SPAN') e.classList.toggle('off', !on);
      else e.classList.toggle('hidden', !on);
    });
    document.querySelectorAll('svg.chart').forEach(function (svg) {
      var has = !filt || svg.querySelector('[data-sid="' + CSS.escape(filt) + '"]');
      svg.classList.toggle('hidden', !has);
    });
  }
  document.getElementById('showall').addEventListener('click', function () {
    filt = 'x'; setFilter('x');
  });
  function chart(view, c, host) {
    var svg = el('svg', {width: W, height: H, 'class': 'chart', 'data-metric': c.metric,
                         'data-scenario': c.scenario}, host);
    var vals = [];
    c.series.forEach(function (s) { s.points.forEach(function (p) {
      if (p[1] !== null) vals.push(c.log ? Math.max(p[1], c.floor || 1e-300) : p[1]); }); });
    var lo = Math.min.apply(null, vals), hi = Math.max.apply(null, vals);
    if (c.log) { lo = Math.floor(Math.log10(lo)); hi = Math.ceil(Math.log10(hi));
                 if (hi === lo) hi = lo + 1; }
    else { if (hi === lo) { hi += 0.5; lo -= 0.5; }
           var pad = (hi - lo) * 0.08; lo -= pad; hi += pad; }
    var n = view.x.length, pw = W - L - R, ph = H - T - B;
    function X(i) { return L + (n > 1 ? i * pw / (n - 1) : pw / 2); }
    function Y(v) { var u = c.log ? Math.log10(Math.max(v, c.floor || 1e-300)) : v;
                    return T + ph - (u - lo) / (hi - lo) * ph; }
    el('text', {x: L, y: 15, 'font-size': 12, 'font-weight': 'bold'}, svg).textContent =
      c.scenario + ': ' + c.metric + ' [' + c.unit + ']';
    el('line', {x1: L, y1: T, x2: L, y2: T + ph, stroke: '#888'}, svg);
    el('line', {x1: L, y1: T + ph, x2: L + pw, y2: T + ph, stroke: '#888'}, svg);
    var step = c.log ? Math.max(1, Math.ceil((hi - lo) / 6)) : (hi - lo) / 4;
    for (var u = lo; u <= hi + 1e-9; u += step) {
      var y = T + ph - (u - lo) / (hi - lo) * ph;
      el('line', {x1: L - 3, y1: y, x2: L + pw, y2: y, stroke: '#eee'}, svg);
      el('text', {x: L - 5, y: y + 4, 'font-size': 10, 'text-anchor': 'end'}, svg).textContent =
        c.log ? '1e' + u : fmt(u);
    }
    view.x.forEach(function (lab, i) {
      var t = el('text', {x: X(i), y: T + ph + 14, 'font-size': 10, 'text-anchor': 'end',
        transform: 'rotate(-30 ' + X(i) + ' ' + (T + ph + 14) + ')'}, svg);
      t.textContent = lab.length > 18 ? lab.slice(0, 17) + '…' : lab;
    });
    c.series.forEach(function (s) {
      var col = color(s.sid), g = el('g', {'data-sid': s.sid}, svg), d = '';
      s.points.forEach(function (p) { if (p[1] !== null)
        d += (d ? 'L' : 'M') + X(p[0]).toFixed(1) + ',' + Y(p[1]).toFixed(1); });
      if (d) {
        var line = el('path', {d: d, fill: 'none', stroke: col, 'stroke-width': 1.5,
                               'class': 'line'}, g);
        line.addEventListener('click', function () { setFilter(s.sid); });
      }
      s.marks.forEach(function (m) {
        var p = s.points.filter(function (q) { return q[0] === m.x; })[0];
        var y = (p && p[1] !== null) ? Y(p[1]) : T + 4;
        var ring = el('circle', {cx: X(m.x), cy: y, r: 7, fill: 'none', 'stroke-width': 2,
          stroke: m.direction === 'worse' || m.direction === 'vanished' ? '#d00' :
                  m.direction === 'better' || m.direction === 'new' ? '#0a0' : '#e90',
          'class': 'mark'}, g);
        el('title', {}, ring).textContent = m.text;
      });
      s.points.forEach(function (p) {
        var x = X(p[0]), label = s.sid + ' | ' + view.axis + ' ' + view.x[p[0]] +
          (view.axis === 'folder' ? ' (' + s.sid.split(' ')[1] + ' ' + p[3] + ')' : '') +
          ': ' + (p[1] === null ? p[2] : c.metric + ' = ' + fmt(p[1]) + ' ' + c.unit);
        var pt;
        if (p[1] === null) {
          pt = el('path', {d: 'M' + (x - 4) + ',' + (T) + 'l8,8m0,-8l-8,8', stroke: col,
                           'stroke-width': 2, 'class': 'pt'}, g);
        } else {
          pt = el('circle', {cx: x, cy: Y(p[1]), r: 3.5, fill: col, 'class': 'pt'}, g);
        }
        pt.setAttribute('data-label', label);
        pt.addEventListener('mouseover', function (e) { show(e, label); });
        pt.addEventListener('mousemove', function (e) { show(e, label); });
        pt.addEventListener('mouseout', hide);
        pt.addEventListener('click', function () { setFilter(s.sid); });
      });
    });
  }
  var host = document.getElementById('views');
  data.views.forEach(function (view) {
    var h = document.createElement('h2'); h.textContent = view.title; host.appendChild(h);
    var leg = document.createElement('div'); leg.className = 'legend'; host.appendChild(leg);
    var seen = {};
    var scen = null, grid = null;
    view.charts.forEach(function (c) {
      if (c.scenario !== scen) {
        scen = c.scenario;
        var h3 = document.createElement('h3'); h3.textContent = scen; host.appendChild(h3);
        grid = document.createElement('div'); grid.className = 'grid'; host.appendChild(grid);
      }
      chart(view, c, grid);
      c.series.forEach(function (s) {
        if (seen[s.sid]) return; seen[s.sid] = 1;
        var sp = document.createElement('span'); sp.setAttribute('data-sid', s.sid);
        sp.innerHTML = '<i style="background:' + color(s.sid) + '"></i>';
        sp.appendChild(document.createTextNode(s.sid));
        sp.addEventListener('click', function () { setFilter(s.sid); });
        leg.appendChild(sp);
      });
    });
  });
  document.body.setAttribute('data-charts', document.querySelectorAll('svg.chart').length);
})();
"""
