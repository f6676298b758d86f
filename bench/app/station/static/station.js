// The live run page: one state object from the server (server-sent events), put into the
// page and three uPlot charts. Every word and figure comes worded and rounded from the
// server (state.view, bench/app/station/view.py), the same text the server wrote into the
// HTML: the script only keeps it current, so a page read without it says the same.
// `window.station` holds the latest state and the charts, for the operator's console and
// for the browser test.
"use strict";
(function () {
  const root = document.getElementById("run");
  if (!root) return;
  const run = root.dataset.run;
  const $ = (id) => document.getElementById(id);
  const station = (window.station = { state: null, charts: {}, updates: 0 });

  function chart(id, label, unit, points) {
    const el = $(id);
    const opts = {
      width: Math.max(320, el.clientWidth || 360), height: 200,
      scales: { x: { time: false } },
      axes: [{ label: "bench time, s" }, { label: unit, size: 70 }],
      series: [{ label: "t, s" }, points
        ? { label: label, stroke: "#b3261e", width: 0, points: { show: true, size: 6, fill: "#b3261e" } }
        : { label: label, stroke: "#2f6fd6", width: 1 }],
    };
    return new uPlot(opts, [[], []], el);
  }

  station.charts.fog = chart("chart-fog", "FOG", "deg/s", false);
  station.charts.drive = chart("chart-drive", "velocity", "deg/s", false);
  station.charts.turns = chart("chart-turns", "deviation", "ppm", true);
  station.charts.turns.axes[0].label = "turn";

  function el(tag, text, cls) {
    const e = document.createElement(tag);
    if (text !== undefined) e.textContent = text;
    if (cls) e.className = cls;
    return e;
  }
  function list(id, items, cls) {
    const ul = $(id);
    ul.textContent = "";
    for (const it of items || []) ul.appendChild(el("li", typeof it === "string" ? it : it.text, cls ? cls(it) : ""));
  }
  function rowsInto(tbody, rows) {
    tbody.textContent = "";
    for (const r of rows || []) {
      const tr = el("tr", undefined, r.class || "");
      for (const c of (r.cells || r)) tr.appendChild(el("td", c));
      tbody.appendChild(tr);
    }
  }
  function table(t, cls) {
    const tb = el("table", undefined, cls);
    tb.id = t.id;
    tb.appendChild(el("caption", t.caption));
    const head = el("thead"), hr = el("tr");
    for (const h of t.header) hr.appendChild(el("th", h));
    head.appendChild(hr);
    tb.appendChild(head);
    const body = el("tbody");
    rowsInto(body, t.rows);
    tb.appendChild(body);
    return tb;
  }

  function renderProgress(p) {
    const bar = $("progress");
    bar.value = p.value;
    bar.textContent = `${Math.round(100 * p.value)} %`;
    bar.className = `${station.state.status}${p.complete ? " complete" : ""}`;
    $("step").textContent = p.line;
    $("eta").textContent = p.detail;
    list("later", p.later);
  }

  function renderHealth(h) {
    $("health-title").textContent = h.title;
    $("last-update").textContent = h.note;
    $("health").classList.toggle("stale", !!h.stale);
    list("health-warnings", h.warnings);
    const head = $("health-table").querySelector("thead tr");
    head.textContent = "";
    for (const c of h.header) head.appendChild(el("th", c));
    rowsInto($("health-table").querySelector("tbody"), h.rows);
  }

  function renderResults(r) {
    $("results-title").textContent = r.title;
    $("verdict").hidden = !r.verdict;
    $("verdict-text").textContent = r.verdict || "";
    $("verdict-text").className = (r.verdict || "").toLowerCase();
    const box = $("results-tables");
    box.textContent = "";
    for (const t of r.tables || []) box.appendChild(table(t, r.final ? "final" : "live"));
    $("results-note").textContent = r.note || "";
  }

  function renderCharts(st) {
    $("charts").hidden = !st.view.charts;
    $("fog-axis").textContent = (st.fog && st.fog.axis) || "-";
    if (st.fog) station.charts.fog.setData([st.fog.t_s, st.fog.rate_dps]);
    if (st.drive) station.charts.drive.setData([st.drive.t_s, st.drive.velocity_dps]);
    if (st.turns && st.turns.deviation_ppm) {
      const n = st.turns.deviation_ppm.length;
      station.charts.turns.setData([Array.from({ length: n }, (_, i) => i + 1), st.turns.deviation_ppm]);
      $("turns-text").textContent = `${st.turns.axis || ""} at ${st.turns.set_rate_dps} deg/s: ${n} ${n === 1 ? "turn" : "turns"}`;
    } else {
      $("turns-text").textContent = "no half timed yet in this run";
    }
  }

  function render(st) {
    station.state = st;
    station.updates += 1;
    const v = st.view;
    // a finished page has no stop form; a run resumed under it gets one with a fresh page
    if (v.live && !$("controls")) { location.reload(); return; }
    $("status").textContent = st.status;
    $("status").className = "badge " + String(st.status).split(" ")[0];
    $("session").textContent = st.session || "-";
    renderProgress(v.progress);
    renderHealth(v.health);
    renderCharts(st);
    renderResults(v.results);
    list("log", v.log, (e) => e.event);
    const controls = $("controls");
    if (controls && !v.live) controls.remove();   // nothing left to stop
    const files = $("files");
    files.textContent = "";
    for (const f of st.files || []) {
      const a = el("a", f);
      a.href = `/files/${encodeURIComponent(run)}/${f}`;
      files.appendChild(a);
      files.appendChild(document.createTextNode(" "));
    }
  }

  render(JSON.parse($("initial-state").textContent));
  const source = new EventSource(`/api/runs/${encodeURIComponent(run)}/stream`);
  source.addEventListener("state", (ev) => render(JSON.parse(ev.data)));

  if (!$("stop")) return;                       // a finished run: no stop form
  $("token").value = sessionStorage.getItem("bench-token") || "";
  $("stop").addEventListener("click", async () => {
    const token = $("token").value;
    sessionStorage.setItem("bench-token", token);
    const resp = await fetch(`/api/runs/${encodeURIComponent(run)}/stop`,
      { method: "POST", headers: { "X-Bench-Token": token } });
    const body = await resp.json().catch(() => ({}));
    $("stop-result").textContent = body.message || body.error || resp.statusText;
  });
})();
