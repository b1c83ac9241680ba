// The live page: polls the run folder's snapshot and redraws. Read-only.
"use strict";
const token = new URLSearchParams(location.search).get("token");
const api = "api/snapshot" + (token ? "?token=" + encodeURIComponent(token) : "");
const POLL_MS = 1000;
const plots = {};

// A duration in words: "1 h 02 min 05 s", never to be read as a clock time.
function duration(s) {
  if (s === null || s === undefined) return "–";
  s = Math.max(0, Math.round(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  const p = (n) => String(n).padStart(2, "0");
  if (h) return h + " h " + p(m) + " min " + p(sec) + " s";
  if (m) return m + " min " + p(sec) + " s";
  return sec + " s";
}

function text(id, value) { document.getElementById(id).textContent = value; }

function plot(id, labels, data) {
  const opts = {
    width: 420, height: 220, scales: { x: { time: false } },
    axes: [{}, { size: 70 }],   // room for labels such as -19.995
    series: [{ label: "t (s)" }].concat(labels.map((l, i) => ({
      label: l, stroke: ["#c33", "#36c", "#999"][i], width: i === 0 ? 1.5 : 1,
      dash: l.startsWith("plan") ? [6, 4] : undefined,
    }))),
  };
  if (!plots[id]) plots[id] = new uPlot(opts, data, document.getElementById(id));
  else plots[id].setData(data);
}

function render(doc) {
  const s = doc.snapshot;
  text("run_id", s.run_id);
  text("serial", s.serial ? "(" + s.serial + ")" : "");
  const st = document.getElementById("state");
  st.textContent = s.state; st.className = "big " + s.state;
  document.getElementById("simulated").className = s.simulated ? "on" : "";
  document.getElementById("paused").className = s.paused ? "on" : "";
  text("step", s.current_index + "/" + s.step_count);
  text("current", s.current_step ? s.current_step : "");
  text("eta", s.state === "done" ? "0 s" : duration(s.eta_s));
  text("age", duration(s.last_event_age_s));
  text("stale", s.stale ? "STALE — controller alive but silent" : "");
  text("holder", s.lock ? "held by pid " + s.lock.pid + " on " + s.lock.host
                        : (s.live ? "controller running" : "no controller"));

  text("end", expectedEnd(s, doc.outcome));
  showOutcome(s, doc.outcome);

  const done = new Set(s.completed);
  const faultSteps = new Set(s.faults.map((f) => f.step_id));
  const total = s.plan.reduce((a, p) => a + p.expected_s, 0) || 1;
  const tl = document.getElementById("timeline");
  tl.replaceChildren(...s.plan.map((p) => {
    const d = document.createElement("div");
    d.style.flex = String(Math.max(p.expected_s / total, 0.002));
    d.className = done.has(p.step_id) ? "done"
      : (p.step_id === s.current_step ? (faultSteps.has(p.step_id) && s.state !== "running"
                                         ? "faultstep" : "current") : "todo");
    d.title = p.step_id + " (" + p.kind + ", " + duration(p.expected_s) + ")";
    return d;
  }));

  const fb = document.getElementById("faultbox");
  if (s.faults.length) {
    const f = s.faults[s.faults.length - 1];
    fb.textContent = "FAULT at " + (f.step_id || "-") + ": " + f.event + " — " + f.detail;
    fb.className = "on";
  } else { fb.className = ""; fb.textContent = ""; }

  const rows = s.events.slice().reverse().map((e) => {
    const tr = document.createElement("tr");
    if (e.fault) tr.className = "fault";
    const when = new Date(e.wall_time * 1000).toISOString().slice(11, 19);
    for (const v of [e.seq, when, e.event, e.step_id, e.detail]) {
      const td = document.createElement("td"); td.textContent = v; tr.appendChild(td);
    }
    return tr;
  });
  document.getElementById("events").replaceChildren(...rows);

  const c = doc.conditions;
  plot("chamber", ["chamber", "plan setpoint"], [c.t_s, c.chamber_c, c.plan_c]);
  plot("table", ["table", "plan rate"], [c.t_s, c.table_dps, c.plan_dps]);
  text("sigstep", doc.signal.step_id || "no data yet");
  plot("signal", ["gyro"], [doc.signal.t_s, doc.signal.gyro]);
  document.body.dataset.seq = s.events.length ? s.events[s.events.length - 1].seq : 0;
  document.body.dataset.state = s.state;
}

// When the run should end, as a clock time with its day, or why there is none.
function expectedEnd(s, outcome) {
  if (s.state === "done") return "– (the run has ended)";
  if (s.eta_s === null || s.eta_s === undefined) return "–";
  const speed = outcome ? outcome.speed : null;
  if (speed === "max") return "as fast as the machine allows (simulated time)";
  const factor = Number(speed) > 0 ? Number(speed) : 1;
  if (s.state !== "running") return "– (not running)";
  const end = new Date(Date.now() + (s.eta_s / factor) * 1000);
  const p = (n) => String(n).padStart(2, "0");
  return end.getFullYear() + "-" + p(end.getMonth() + 1) + "-" + p(end.getDate()) + " "
    + p(end.getHours()) + ":" + p(end.getMinutes()) + " (this computer's time)";
}

function showOutcome(s, outcome) {
  const box = document.getElementById("verdictbox");
  if (!outcome || !outcome.verdict) { box.className = ""; return; }
  box.className = "on " + outcome.verdict;
  text("verdict", outcome.verdict);
  const why = outcome.failed.length ? "failed: " + outcome.failed.join(", ")
    : outcome.reasons.join("; ");
  text("verdict_detail", why);
  const link = document.getElementById("report_link");
  link.style.display = outcome.report ? "" : "none";
  if (outcome.report) link.href = outcome.report + (token ? "?token=" + encodeURIComponent(token) : "");
}

async function poll() {
  try {
    const r = await fetch(api, { cache: "no-store" });
    const doc = await r.json();
    if (!r.ok) throw new Error(doc.error || r.status);
    render(doc);
    text("error", "");
  } catch (err) {
    text("error", "cannot read the run: " + err.message);
  }
  setTimeout(poll, POLL_MS);
}
poll();
