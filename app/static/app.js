// The design page: one form, one POST /v1/compare, a table, two plots and a CSV download.
"use strict";

const FAMILIES = {
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

const $ = (id) => document.getElementById(id);
const form = $("design-form");
let lastResult = null;
let selectedRow = 0;
let motionPlot = null;
let sensitivityPlot = null;

function numberOrNull(id) {
  const text = $(id).value.trim();
  return text === "" ? null : Number(text);
}

function buildRequest() {
  const preset = $("plant-preset").value;
  const plant = preset === "mode"
    ? { kind: "mode", natural_frequency_hz: numberOrNull("natural_frequency_hz"), damping_ratio: numberOrNull("damping_ratio") ?? 0 }
    : { ...PRESETS[preset] };
  const moveKind = form.elements.move.value;
  const request = { plant, include_curves: true };
  request[moveKind] = numberOrNull("move-value");
  const limits = {};
  for (const name of ["max_velocity", "max_acceleration", "max_jerk", "max_torque_nm"]) {
    const value = numberOrNull(name);
    if (value !== null) limits[name] = value;
  }
  request.limits = limits;
  const duration = numberOrNull("duration_s");
  if (duration !== null) request.duration_s = duration;
  const family = $("family").value;
  if (family !== "all") request.families = [family];
  return request;
}

function clearErrors() {
  for (const el of document.querySelectorAll(".field-error, .form-error")) el.textContent = "";
  for (const el of document.querySelectorAll("[aria-invalid]")) el.removeAttribute("aria-invalid");
}

// Put each problem+json error next to the field it names (the longest matching data-field).
function showProblem(problem) {
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
  $("form-error").textContent = placed ? "" : (problem.title || "Error") + ": " + problem.detail;
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
  if (!row || !row.curves || !row.curves.sensitivity) return;
  const curve = row.curves.sensitivity;
  sensitivityPlot = new uPlot({
    width: plotWidth(el), height: 260,
    scales: { x: { time: false } },
    axes: [{ label: "fn / fn,e" }, { label: "percentage vibration V (%)" }],
    series: [{ label: "ratio" }, { label: "V %", stroke: "#2a8a4a", width: 2 }],
  }, [curve.frequency_ratio, curve.percentage_vibration], el);
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

async function design(event) {
  event.preventDefault();
  clearErrors();
  $("status").textContent = "Designing…";
  $("design-button").disabled = true;
  try {
    const response = await fetch("/v1/compare", {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(buildRequest()),
    });
    const body = await response.json();
    if (!response.ok) {
      showProblem(body);
      $("status").textContent = "";
      return;
    }
    lastResult = body;
    renderTable(body);
    selectRow(0);
    $("status").textContent = body.rows.length ? `${body.rows.length} design(s).` : "No family could meet the limits.";
  } catch (error) {
    $("form-error").textContent = "The service did not answer: " + error;
    $("status").textContent = "";
  } finally {
    $("design-button").disabled = false;
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
}

for (const [value, label] of Object.entries(FAMILIES)) {
  const option = document.createElement("option");
  option.value = value;
  option.textContent = label;
  $("family").appendChild(option);
}
$("plant-preset").addEventListener("change", syncForm);
for (const radio of form.elements.move) radio.addEventListener("change", syncForm);
$("quantity").addEventListener("change", drawMotion);
$("csv-button").addEventListener("click", downloadCsv);
form.addEventListener("submit", design);
window.addEventListener("resize", () => { drawMotion(); drawSensitivity(); });
syncForm();
