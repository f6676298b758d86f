// The live run page: one state object from the server (server-sent events), drawn into
// the step line, the progress bar and three uPlot charts. `window.station` holds the
// latest state and the charts, for the operator's console and for the browser test.
"use strict";
(function () {
  const root = document.getElementById("run");
  if (!root) return;
  const run = root.dataset.run;
  const $ = (id) => document.getElementById(id);
  const station = (window.station = { state: null, charts: {}, updates: 0 });

  function duration(s) {
    if (s === null || s === undefined || !isFinite(s)) return "-";
    s = Math.max(0, Math.round(s));
    const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
    if (h) return `${h} h ${m} min`;
    if (m) return `${m} min ${r} s`;
    return `${r} s`;
  }

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

  function render(st) {
    station.state = st;
    station.updates += 1;
    const p = st.progress || {};
    $("status").textContent = st.status;
    $("status").className = "badge " + String(st.status).split(" ")[0];
    $("session").textContent = st.session || "-";
    $("bar-fill").style.width = (100 * (p.fraction || 0)).toFixed(1) + "%";
    if (p.step) {
      $("step").textContent = `Step ${p.step.number} of ${p.steps}: ${p.step.axis || ""} ${p.step.action} - ${p.step.describe}`;
    } else {
      $("step").textContent = st.status === "created" ? "not started" : "-";
    }
    const speed = p.speed ? ` (measured speed ${p.speed.toFixed(1)} bench s per wall s)` : "";
    $("eta").textContent = `${p.steps_done || 0} of ${p.steps || 0} steps done; bench time left ${duration(p.bench_left_s)}, ` +
      `wall time left ${duration(p.wall_left_s)}${speed}`;
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
    const log = $("log");
    log.textContent = "";
    for (const e of st.log || []) {
      const li = document.createElement("li");
      li.className = e.event;
      let text = `${(e.utc || "").slice(11, 19)} UTC, session ${e.session}: ${e.event}`;
      if (e.reason) text += ` - ${e.reason}`;
      if (e.text) text += ` - ${e.text} (${e.answered || ""})`;
      if (e.event === "exit") text += ` with status ${e.status}`;
      if (e.event === "pair") text += ` ${e.axis} +/-${e.unit ? e.unit.split("/")[1] : ""}`;
      if (e.error) text += ` (${e.error})`;
      li.textContent = text;
      log.appendChild(li);
    }
    const files = $("files");
    files.textContent = "";
    for (const f of st.files || []) {
      const a = document.createElement("a");
      a.href = `/files/${encodeURIComponent(run)}/${f}`;
      a.textContent = f;
      files.appendChild(a);
      files.appendChild(document.createTextNode(" "));
    }
  }

  render(JSON.parse($("initial-state").textContent));
  const source = new EventSource(`/api/runs/${encodeURIComponent(run)}/stream`);
  source.addEventListener("state", (ev) => render(JSON.parse(ev.data)));

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
