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

  function num(v, digits) {
    return (v === null || v === undefined || !isFinite(v)) ? "-" : Number(v).toPrecision(digits);
  }
  function ppm(v, digits) {
    return (v === null || v === undefined || !isFinite(v)) ? "-" : (v * 1e6).toFixed(digits);
  }
  function age(s) {
    return (s === null || s === undefined) ? "-" : `${s.toFixed(s < 10 ? 1 : 0)} s ago`;
  }
  function cells(tr, values) {
    for (const v of values) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
  }

  function renderHealth(h) {
    if (!h) return;
    const running = station.state && station.state.status === "running";
    $("last-update").textContent = h.last_update_s === null || h.last_update_s === undefined
      ? "" : `- last update ${age(h.last_update_s)}${h.stale ? " (STALE)" : ""}`;
    $("health").classList.toggle("stale", !!h.stale);
    const ul = $("health-warnings");
    ul.textContent = "";
    for (const w of h.warnings || []) {
      const li = document.createElement("li");
      li.textContent = w;
      ul.appendChild(li);
    }
    const body = $("health-table").querySelector("tbody");
    body.textContent = "";
    for (const a of h.axes || []) {
      const tr = document.createElement("tr");
      const tail = a.fog_tail_crc_errors === undefined ? "-" : `${a.fog_tail_crc_errors} / ${a.fog_tail_lost_frames}`;
      cells(tr, [a.axis, running ? age(a.fog_age_s) : "-", String(a.fog_lost_in_halves), tail,
        running ? age(a.drive_age_s) : "-", running ? age(a.counter_age_s) : "-"]);
      body.appendChild(tr);
    }
  }

  function renderResults(st) {
    const final = (st.final || []).length > 0;
    const rows = final ? st.final : (st.results || []);
    $("results-title").textContent = final
      ? "Final results (result.json; the certificate prints these)"
      : "Results as they come (first look per pair; the certificate is computed again from the raw data)";
    $("results-table").classList.toggle("final", final);
    const body = $("results-table").querySelector("tbody");
    body.textContent = "";
    for (const r of rows) {
      const tr = document.createElement("tr");
      tr.className = r.verdict || "";
      cells(tr, [r.axis, (r.set_rate_dps > 0 ? "+" : "") + r.set_rate_dps,
        `${num(r.k, 7)} ± ${num(r.k_U, 2)}`, `${num(r.w0_dps, 4)} ± ${num(r.w0_U_dps, 2)}`,
        `${ppm(r.rate_error_rel, 3)} ± ${ppm(r.rate_error_U_rel, 3)}`, ppm(r.rate_instability_rel, 3),
        r.turns === undefined || r.turns === null ? "-" : String(r.turns), r.verdict || "-"]);
      body.appendChild(tr);
    }
    $("results-none").style.display = rows.length ? "none" : "";
  }

  function milestone(e) {
    const rate = e.rate_dps !== undefined ? `${e.rate_dps > 0 ? "+" : ""}${e.rate_dps} deg/s` : "";
    const mag = e.unit ? e.unit.split("/")[1].replace("dps", " deg/s") : "";
    if (e.event === "settled") {
      const set = mag ? `${e.rate_dps < 0 ? "-" : "+"}${mag}` : rate;
      return `settled: ${e.axis || ""} at ${set}` + (mag ? ` (drive reads ${num(e.rate_dps, 7)} deg/s)` : "");
    }
    if (e.event === "pair") {
      return `pair analysed: ${e.axis || ""} +/-${mag}: k = ${num(e.k, 7)} ± ${num(e.k_u, 2)}, ` +
        `ω0 = ${num(e.w0_dps, 4)} ± ${num(e.w0_u_dps, 2)} deg/s`;
    }
    if (e.event === "pair_failed") return `pair first look failed: ${e.axis || ""} +/-${mag} (${e.error || ""})`;
    return null;
  }

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
      const said = milestone(e);
      let text = `${(e.utc || "").slice(11, 19)} UTC, session ${e.session}: ${said || e.event}`;
      if (!said) {
        if (e.reason) text += ` - ${e.reason}`;
        if (e.text) text += ` - ${e.text} (${e.answered || ""})`;
        if (e.event === "exit") text += ` with status ${e.status}`;
        if (e.error) text += ` (${e.error})`;
      }
      li.textContent = text;
      log.appendChild(li);
    }
    renderHealth(st.health);
    renderResults(st);
    const controls = $("controls");
    if (controls && st.status !== "running" && st.status !== "created") controls.remove();   // nothing left to stop
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
