// The design page: one form, one POST /v1/compare (and, with a robustness band, one POST
// /v1/profiles/time-optimal), a table, the plots, a trade-off curve on demand and a CSV download.
"use strict";

const FAMILIES = {
  time_optimal: "Time-optimal",
  pseudo_polynomial: "Pseudo-polynomial (Incerti)",
  stap: "Trapezoidal acceleration, STAP (Cusimano)",
  smoother: "Smoother (Biagiotti)",
  input_shaped: "Input shaping (Chatlatanagulchai)",
};

const PRESETS = {
  incerti: {
    kind: "belt_platform", platform_inertia_kgm2: 6, branch_stiffness_n_per_m: 90000,
    branch_damping_ns_per_m: 150, motor_pulley_radius_m: 0.06, platform_pulley_radius_m: 0.18, gear_ratio: 0.1,
  },
  cusimano: {
    kind: "two_inertia", motor_inertia_kgm2: 0.005, load_inertia_kgm2: 0.005,
    stiffness_nm_per_rad: 12.63309363339438, damping_nms_per_rad: 0,
  },
  chatlatanagulchai: {
    kind: "rigid_flexible", drive_mass_kg: 2, load_mass_kg: 3, stiffness_n_per_m: 1,
    damping_ns_per_m: 0.1, drive_damping_ns_per_m: 30,
  },
  biagiotti: { kind: "mode", natural_frequency_hz: 19.6895152, damping_ratio: 0.1265341 },
};

// The sensitivity grid every design is evaluated on (compare's default, sent explicitly to both endpoints).
const SENSITIVITY = { min_ratio: 0.5, max_ratio: 1.5, count: 201 };
// Band half-widths of the trade-off curve "What robustness costs".
const TRADEOFF_HALF_WIDTHS = [0, 0.05, 0.1, 0.15, 0.2];
const TIME_OPTIMAL_ENDPOINT = "/v1/profiles/time-optimal";

const $ = (id) => document.getElementById(id);
const form = $("design-form");
let lastResult = null;
let lastBand = null; // the robustness band the shown results were designed with (null: none)
let selectedRow = 0;
let motionPlot = null;
let sensitivityPlot = null;
let tradeoffPlot = null;
let tradeoffRows = null;
let tradeoffKey = null; // tradeoffKeyOf() of the inputs the shown trade-off was computed for
let designSeq = 0;
let tradeoffSeq = 0;

function numberOrNull(id) {
  const text = $(id).value.trim();
  return text === "" ? null : Number(text);
}

// Plant, move and limits: what compare and the time-optimal endpoint share.
function buildCommon() {
  const preset = $("plant-preset").value;
  const plant = preset === "mode"
    ? { kind: "mode", natural_frequency_hz: numberOrNull("natural_frequency_hz"), damping_ratio: numberOrNull("damping_ratio") ?? 0 }
    : { ...PRESETS[preset] };
  const moveKind = form.elements.move.value;
  const request = { plant };
  request[moveKind] = numberOrNull("move-value");
  const limits = {};
  for (const name of ["max_velocity", "max_acceleration", "max_jerk", "max_torque_nm"]) {
    const value = numberOrNull(name);
    if (value !== null) limits[name] = value;
  }
  request.limits = limits;
  return request;
}

function buildRequest() {
  const request = { ...buildCommon(), include_curves: true, sensitivity: { ...SENSITIVITY } };
  const duration = numberOrNull("duration_s");
  if (duration !== null) request.duration_s = duration;
  const family = $("family").value;
  if (family !== "all") request.families = [family];
  return request;
}

// The robustness control: null (none), or the band as the time-optimal endpoint takes it.
function readBand() {
  if ($("robustness").value !== "band") return null;
  const percent = numberOrNull("band-percent");
  const vmax = numberOrNull("max-vibration");
  const range = percent === null ? null : [1 - percent / 100, 1 + percent / 100];
  return { percent, vmax, robustness: { frequency_ratio_range: range, max_percentage_vibration: vmax } };
}

function robustRequest(band) {
  return { ...buildCommon(), robustness: band.robustness, sensitivity: { ...SENSITIVITY } };
}

function clearErrors() {
  for (const el of document.querySelectorAll(".field-error, .form-error")) el.textContent = "";
  for (const el of document.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
}

// Put each problem+json error next to the field it names (the longest matching data-field).
// context names the call in the form-wide message when no field matches.
function showProblem(problem, context = "") {
  const errors = problem.errors && problem.errors.length ? problem.errors : [{ field: problem.field, rule: problem.detail }];
  let placed = false;
  for (const error of errors) {
    const field = error.field || "";
    const candidates = [...document.querySelectorAll("[data-field]")]
      .filter((el) => field === el.dataset.field || field.startsWith(el.dataset.field + ".") || field.startsWith(el.dataset.field + "["))
      .sort((a, b) => b.dataset.field.length - a.dataset.field.length);
    const target = candidates[0];
    const slot = target && $("err-" + target.dataset.field);
    if (slot) {
      slot.textContent = error.rule || problem.detail;
      target.setAttribute("aria-invalid", "true");
      placed = true;
    }
  }
  $("form-error").textContent = placed ? "" : context + (problem.title || "Error") + ": " + problem.detail;
  const firstInvalid = document.querySelector("[aria-invalid=true]");
  if (firstInvalid) firstInvalid.focus();
}

function fmt(value, digits = 4) {
  if (value === null || value === undefined) return "–";
  if (typeof value === "boolean") return value ? "yes" : "no";
  return Number(value).toPrecision(digits);
}

function designName(row) {
  const family = FAMILIES[row.family] || row.family;
  if (row.variantName) return `${family}: ${row.variantName}`;
  const variant = (row.label || "").split("/")[1];
  const SHAPERS = ["zv", "mzv", "zvd", "ei"];
  const name = variant && (SHAPERS.includes(variant) ? variant.toUpperCase() : variant.replace(/_/g, " "));
  return name ? `${family}: ${name}` : family;
}

function renderTable(result) {
  const body = $("compare-table").querySelector("tbody");
  body.innerHTML = "";
  result.rows.forEach((row, index) => {
    const tr = document.createElement("tr");
    tr.tabIndex = 0;
    tr.dataset.index = String(index);
    tr.setAttribute("aria-selected", String(index === selectedRow));
    tr.dataset.label = row.label || row.family;
    const [low, high] = row.band_5_percent || [undefined, undefined];
    const band = row.band_5_percent
      ? `${low === null ? "below 0.5" : fmt(low, 3)} – ${high === null ? "above 1.5" : fmt(high, 3)}` : "–";
    const cells = [
      designName(row), fmt(row.motion_time_s), fmt(row.settling_time_s),
      fmt(row.percentage_vibration, 3), band, fmt(row.peak_velocity), fmt(row.peak_acceleration),
      fmt(row.peak_jerk), fmt(row.peak_motor_torque_nm), fmt(row.limits_met),
    ];
    for (const text of cells) {
      const td = document.createElement("td");
      td.textContent = text;
      tr.appendChild(td);
    }
    tr.addEventListener("click", () => selectRow(index));
    tr.addEventListener("keydown", (event) => {
      if (event.key === "Enter" || event.key === " ") { event.preventDefault(); selectRow(index); }
    });
    body.appendChild(tr);
  });
  const list = $("unavailable");
  list.innerHTML = "";
  for (const item of result.unavailable) {
    const li = document.createElement("li");
    li.textContent = `${FAMILIES[item.family] || item.family}: ${item.reason}`;
    list.appendChild(li);
  }
}

function plotWidth(el) {
  return Math.max(320, Math.min(el.clientWidth || 800, 1100));
}

function drawMotion() {
  const row = lastResult && lastResult.rows[selectedRow];
  const el = $("motion-plot");
  if (motionPlot) { motionPlot.destroy(); motionPlot = null; }
  if (!row || !row.curves) return;
  const quantity = $("quantity").value;
  const profile = row.curves.profile;
  const load = row.curves.load;
  $("plot-title").textContent = `Motor and load: ${designName(row)}`;
  // The load has its own axis (right): a belt platform turns 1/30 of the motor, for example.
  motionPlot = new uPlot({
    width: plotWidth(el), height: 300,
    scales: { x: { time: false } },
    axes: [{ label: "time (s)" }, { label: "motor " + quantity, stroke: "#1f6fb4" },
      { label: "load " + quantity, scale: "load", side: 1, grid: { show: false }, stroke: "#d9541e" }],
    series: [{ label: "t (s)" }, { label: "motor " + quantity, stroke: "#1f6fb4", width: 2 },
      { label: "load " + quantity, stroke: "#d9541e", width: 2, scale: "load" }],
  }, [profile.time_s, profile[quantity], load[quantity]], el);
}

function drawSensitivity() {
  const row = lastResult && lastResult.rows[selectedRow];
  const el = $("sensitivity-plot");
  if (sensitivityPlot) { sensitivityPlot.destroy(); sensitivityPlot = null; }
  $("sensitivity-note").textContent = "";
  if (!row || !row.curves || !row.curves.sensitivity) return;
  const curve = row.curves.sensitivity;
  const achieved = achievedBand(row);
  sensitivityPlot = new uPlot({
    width: plotWidth(el), height: 260,
    scales: { x: { time: false } },
    axes: [{ label: "fn / fn,e" }, { label: "percentage vibration V (%)" }],
    series: [{ label: "ratio" }, { label: "V %", stroke: "#2a8a4a", width: 2 }],
    hooks: { draw: [(u) => drawBandMarks(u, lastBand, achieved)] },
  }, [curve.frequency_ratio, curve.percentage_vibration], el);
  describeBands(row, achieved);
}

function achievedBand(row) {
  const robustness = row.design && row.design.robustness;
  return (robustness && robustness.achieved && robustness.achieved.frequency_ratio_range) || null;
}

// The requested band (shaded, with its V max as a dashed line) and the achieved one (two dashed lines),
// as elements over the plot's canvas, placed in the plot's own coordinates on every redraw.
function drawBandMarks(u, band, achieved) {
  for (const old of u.over.querySelectorAll(".band-mark")) old.remove();
  const [xMin, xMax] = [u.scales.x.min, u.scales.x.max];
  const width = u.over.clientWidth;
  const x = (value) => Math.max(0, Math.min(width, u.valToPos(Math.max(xMin, Math.min(xMax, value)), "x")));
  const mark = (className, style, title) => {
    const el = document.createElement("div");
    el.className = "band-mark " + className;
    Object.assign(el.style, style);
    el.title = title;
    u.over.appendChild(el);
    return el;
  };
  if (band && band.robustness.frequency_ratio_range) {
    const [low, high] = band.robustness.frequency_ratio_range;
    const el = mark("band-requested", { left: x(low) + "px", width: Math.max(1, x(high) - x(low)) + "px" },
      `requested band ${fmt(low, 3)} – ${fmt(high, 3)}`);
    el.dataset.low = String(low);
    el.dataset.high = String(high);
    const v = band.vmax;
    if (v !== null && v >= u.scales.y.min && v <= u.scales.y.max) {
      mark("band-vmax", { top: u.valToPos(v, "y") + "px" }, `V max ${fmt(v, 3)} %`);
    }
  }
  if (achieved) {
    const [low, high] = achieved;
    for (const [value, side] of [[low, "low"], [high, "high"]]) {
      if (value < xMin || value > xMax) continue; // the achieved band runs past the plotted ratios
      const el = mark("band-achieved band-achieved-" + side, { left: x(value) + "px" },
        `achieved band ${side} end ${fmt(value, 4)}`);
      el.dataset.value = String(value);
    }
  }
}

// A ratio or a percentage as typed, without trailing zeros: 0.9, 1.1, 0.8220, 5.
function plain(value, decimals = 4) {
  return String(Number(Number(value).toFixed(decimals)));
}

function describeBands(row, achieved) {
  const parts = [];
  if (lastBand && lastBand.robustness.frequency_ratio_range) {
    const [low, high] = lastBand.robustness.frequency_ratio_range;
    parts.push(`Shaded: the requested band ${plain(low)} – ${plain(high)}; dotted line: its V max ${plain(lastBand.vmax, 3)} %.`);
  }
  if (achieved) {
    parts.push(`Dashed lines: the band ${plain(achieved[0], 3)} – ${plain(achieved[1], 3)} achieved by ${designName(row)}.`);
  }
  $("sensitivity-note").textContent = parts.join(" ");
}

function selectRow(index) {
  selectedRow = index;
  for (const tr of $("compare-table").querySelectorAll("tbody tr")) {
    tr.setAttribute("aria-selected", String(Number(tr.dataset.index) === index));
  }
  $("csv-button").disabled = !lastResult || !lastResult.rows[index];
  drawMotion();
  drawSensitivity();
}

async function postJson(url, body) {
  const response = await fetch(url, {
    method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body),
  });
  return { ok: response.ok, body: await response.json() };
}

// A time-optimal profile response as a compare row (the endpoint answers in its own blocks).
function robustRow(body, request, band) {
  const m = body.metrics;
  return {
    family: "time_optimal", label: "time_optimal robust", variantName: `robust ±${band.percent} %`,
    endpoint: TIME_OPTIMAL_ENDPOINT, request,
    motion_time_s: m.motion_time_s, settling_time_s: m.settling_time_s,
    percentage_vibration: m.percentage_vibration,
    band_5_percent: body.sensitivity ? body.sensitivity.band_5_percent : null,
    peak_velocity: m.peak_velocity, peak_acceleration: m.peak_acceleration, peak_jerk: m.peak_jerk,
    peak_motor_torque_nm: m.peak_motor_torque_nm, limits_met: body.limits_met,
    warnings: body.warnings, design: body.design,
    curves: { profile: body.profile, load: body.load, sensitivity: body.sensitivity },
  };
}

// Compare's order: settling time (never-settling last), then motion time.
function insertSorted(rows, row) {
  const key = (r) => [r.settling_time_s === null ? Infinity : r.settling_time_s, r.motion_time_s];
  const [s, t] = key(row);
  let index = rows.findIndex((r) => { const [rs, rt] = key(r); return rs > s || (rs === s && rt > t); });
  if (index < 0) index = rows.length;
  rows.splice(index, 0, row);
  return index;
}

function clearResults() {
  lastResult = null;
  lastBand = null;
  $("compare-table").querySelector("tbody").innerHTML = "";
  $("unavailable").innerHTML = "";
  selectRow(0);
}

async function design(event) {
  event.preventDefault();
  const seq = ++designSeq;
  clearErrors();
  $("status").textContent = "Designing…";
  $("design-button").disabled = true;
  const request = buildRequest();
  const band = readBand();
  const family = $("family").value;
  const wantRobust = band !== null && (family === "all" || family === "time_optimal");
  if (tradeoffKey !== null && tradeoffKey !== tradeoffKeyOf(band)) {
    clearTradeoff("The inputs changed: press Trade-off again.");
  }
  try {
    const robustBody = wantRobust ? robustRequest(band) : null;
    const [compared, robust] = await Promise.all([
      postJson("/v1/compare", request), wantRobust ? postJson(TIME_OPTIMAL_ENDPOINT, robustBody) : null,
    ]);
    if (seq !== designSeq) return; // a newer Design is under way
    if (!compared.ok) {
      clearResults();
      showProblem(compared.body);
      $("status").textContent = "";
      return;
    }
    const result = compared.body;
    let select = 0;
    lastBand = null;
    if (robust && robust.ok) {
      lastBand = band;
      select = insertSorted(result.rows, robustRow(robust.body, robustBody, band));
    }
    lastResult = result;
    renderTable(result);
    selectRow(select);
    let status = result.rows.length ? `${result.rows.length} design(s).` : "No family could meet the limits.";
    if (robust && !robust.ok) {
      showProblem(robust.body, "Robust time-optimal design: ");
      status += " The robust time-optimal design failed.";
    }
    $("status").textContent = status;
  } catch (error) {
    if (seq !== designSeq) return;
    $("form-error").textContent = "The service did not answer: " + error;
    $("status").textContent = "";
  } finally {
    if (seq === designSeq) $("design-button").disabled = false;
  }
}

// What a trade-off depends on: plant, move, limits and the V max of the band (if one is set).
function tradeoffKeyOf(band) {
  return JSON.stringify([buildCommon(), band ? band.vmax : null]);
}

function clearTradeoff(note = "Press Trade-off to compute the curve.") {
  if (tradeoffPlot) { tradeoffPlot.destroy(); tradeoffPlot = null; }
  tradeoffRows = null;
  tradeoffKey = null;
  $("tradeoff-table").hidden = true;
  $("tradeoff-table").querySelector("tbody").innerHTML = "";
  $("tradeoff-note").textContent = note;
}

function drawTradeoff() {
  const el = $("tradeoff-plot");
  if (tradeoffPlot) { tradeoffPlot.destroy(); tradeoffPlot = null; }
  if (!tradeoffRows) return;
  const ms = (value) => (value === null || value === undefined ? null : value * 1000);
  const data = [
    tradeoffRows.map((row) => row.half_width * 100),
    tradeoffRows.map((row) => ms(row.duration_s)),
    tradeoffRows.map((row) => ms(row.lower_bound_s)),
  ];
  tradeoffPlot = new uPlot({
    width: Math.min(plotWidth(el), 640), height: 220,
    scales: { x: { time: false } },
    axes: [{ label: "band half-width (± %)" }, { label: "duration (ms)" }],
    series: [
      { label: "± %" },
      { label: "minimum duration (ms)", stroke: "#1f6fb4", width: 2, points: { show: true, size: 8 } },
      { label: "lower bound (ms)", stroke: "#8a8f98", width: 1.5, dash: [6, 4], points: { show: true, size: 6 } },
    ],
  }, data, el);
}

function renderTradeoffTable() {
  const body = $("tradeoff-table").querySelector("tbody");
  body.innerHTML = "";
  for (const row of tradeoffRows) {
    const tr = document.createElement("tr");
    const cells = [
      `± ${plain(row.half_width * 100, 2)}`,
      row.duration_s === null ? "–" : fmt(row.duration_s * 1000, 5),
      row.lower_bound_s === null ? "–" : fmt(row.lower_bound_s * 1000, 5),
      row.status === "ok" ? "ok" : `${row.status}${row.reason ? ": " + row.reason : ""}`,
    ];
    for (const text of cells) {
      const td = document.createElement("td");
      td.textContent = text;
      tr.appendChild(td);
    }
    body.appendChild(tr);
  }
  $("tradeoff-table").hidden = false;
}

async function computeTradeoff() {
  const seq = ++tradeoffSeq;
  clearErrors();
  clearTradeoff("");
  const button = $("tradeoff-button");
  const progress = $("tradeoff-progress");
  const band = readBand();
  const key = tradeoffKeyOf(band);
  // With a band, its V max (and the robust design itself) goes along: the rows use the same V max.
  const request = { ...buildCommon(), tradeoff: TRADEOFF_HALF_WIDTHS };
  if (band) request.robustness = band.robustness;
  button.disabled = true;
  progress.hidden = false;
  $("tradeoff-section").setAttribute("aria-busy", "true");
  const started = performance.now();
  const tick = () => {
    const seconds = Math.round((performance.now() - started) / 1000);
    $("tradeoff-status").textContent = `Computing ${TRADEOFF_HALF_WIDTHS.length} minimum-time designs… ${seconds} s`;
  };
  tick();
  const timer = setInterval(tick, 1000);
  try {
    const answer = await postJson(TIME_OPTIMAL_ENDPOINT, request);
    if (seq !== tradeoffSeq) return;
    if (!answer.ok) {
      showProblem(answer.body, "Trade-off: ");
      $("tradeoff-status").textContent = "";
      return;
    }
    tradeoffRows = answer.body.tradeoff || [];
    tradeoffKey = key;
    drawTradeoff();
    renderTradeoffTable();
    const failed = tradeoffRows.filter((row) => row.status !== "ok").length;
    const vmax = band ? band.vmax : null;
    $("tradeoff-note").textContent = `Each band [1 − h, 1 + h] of fn / fn,e with V ≤ ${vmax === null ? "5" : plain(vmax, 3)} %;`
      + " h = 0 is zero residual at the mode." + (failed ? ` ${failed} half-width(s) without a design.` : "");
    const seconds = ((performance.now() - started) / 1000).toFixed(1);
    $("tradeoff-status").textContent = `${tradeoffRows.length} point(s) in ${seconds} s.`;
  } catch (error) {
    if (seq !== tradeoffSeq) return;
    $("form-error").textContent = "The service did not answer: " + error;
    $("tradeoff-status").textContent = "";
  } finally {
    clearInterval(timer);
    if (seq === tradeoffSeq) {
      button.disabled = false;
      progress.hidden = true;
      $("tradeoff-section").removeAttribute("aria-busy");
    }
  }
}

async function downloadCsv() {
  const row = lastResult && lastResult.rows[selectedRow];
  if (!row) return;
  const response = await fetch(row.endpoint + "?format=csv", {
    method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(row.request),
  });
  if (!response.ok) { showProblem(await response.json()); return; }
  const blob = await response.blob();
  const link = document.createElement("a");
  link.href = URL.createObjectURL(blob);
  link.download = `${(row.label || row.family).replace("/", "-")}-profile.csv`;
  document.body.appendChild(link);
  link.click();
  link.remove();
}

function syncForm() {
  $("mode-fields").hidden = $("plant-preset").value !== "mode";
  const velocity = form.elements.move.value === "target_velocity";
  $("move-label").textContent = velocity ? "Target velocity (rad/s or m/s)" : "Displacement (rad or m)";
  $("move-value").dataset.field = velocity ? "target_velocity" : "displacement";
  $("band-fields").hidden = $("robustness").value !== "band";
}

for (const [value, label] of Object.entries(FAMILIES)) {
  const option = document.createElement("option");
  option.value = value;
  option.textContent = label;
  $("family").appendChild(option);
}
$("plant-preset").addEventListener("change", syncForm);
$("robustness").addEventListener("change", syncForm);
$("tradeoff-button").addEventListener("click", computeTradeoff);
for (const radio of form.elements.move) radio.addEventListener("change", syncForm);
$("quantity").addEventListener("change", drawMotion);
$("csv-button").addEventListener("click", downloadCsv);
form.addEventListener("submit", design);
window.addEventListener("resize", () => { drawMotion(); drawSensitivity(); drawTradeoff(); });
syncForm();
