// The design page. Design sends the closed-form families first (a POST /v1/compare each for the input
// shapers, STAP and the smoothers, with POST /v1/plants/analyze for the plant's modes and G(0)), plots
// the first row as soon as it arrives, then runs the solver families (time-optimal, pseudo-polynomial),
// the robust time-optimal design, a chosen shaper and a paper's example in parallel, each row filled in
// when it arrives with a progress line while it runs. Plant fields, presets and the shaper list come from
// the service itself (/openapi.json, GET /v1/shapers): one source of truth.
"use strict";

const FAMILIES = {
  time_optimal: "Time-optimal",
  pseudo_polynomial: "Pseudo-polynomial (Incerti)",
  stap: "Trapezoidal acceleration, STAP (Cusimano)",
  smoother: "Smoother (Biagiotti)",
  input_shaped: "Input shaping (Chatlatanagulchai)",
};
const ENDPOINT_FAMILY = {
  "/v1/compare": "all",
  "/v1/profiles/time-optimal": "time_optimal",
  "/v1/profiles/pseudo-polynomial": "pseudo_polynomial",
  "/v1/profiles/stap": "stap",
  "/v1/profiles/smoother": "smoother",
  "/v1/profiles/input-shaped": "input_shaped",
};
// Closed forms run in a thread of the HTTP process (about 0.4 s together for the default move); the
// solver families search with HiGHS or IPOPT on the worker pool (seconds, far more on a loaded machine).
const FAST_FAMILIES = ["input_shaped", "stap", "smoother"];
const SLOW_FAMILIES = ["time_optimal", "pseudo_polynomial"];
const PLANT_SCHEMAS = {
  mode: "ModeIn", two_inertia: "TwoInertiaIn", belt_platform: "BeltPlatformIn", rigid_flexible: "RigidFlexibleIn",
};
const DEFAULT_MODE = { natural_frequency_hz: 5, damping_ratio: 0.02 };
// Fields of an example the form shows; any other field is an option of its endpoint, sent with the
// example's own row ("paper's example"). A tradeoff is the Trade-off button's.
const FORM_KEYS = new Set(["plant", "displacement", "target_velocity", "limits", "duration_s", "sample_period_s",
  "horizon_s", "sensitivity", "shaper", "tradeoff", "robustness"]);
const LIMIT_NAMES = ["max_velocity", "max_acceleration", "max_jerk", "max_torque_nm"];

// The sensitivity grid every design is evaluated on (compare's default, sent explicitly to every endpoint,
// so that all curves share one x axis).
const SENSITIVITY = { min_ratio: 0.5, max_ratio: 1.5, count: 201 };
// Band half-widths of the trade-off curve "What robustness costs".
const TRADEOFF_HALF_WIDTHS = [0, 0.05, 0.1, 0.15, 0.2];
const TIME_OPTIMAL_ENDPOINT = "/v1/profiles/time-optimal";
const PALETTE = ["#1f6fb4", "#d9541e", "#2a8a4a", "#8e44ad", "#b8860b", "#17a2b8", "#c2185b", "#5d6d7e", "#6b8e23",
  "#a0522d"];
const MOTOR_COLOUR = "#1f6fb4";
const LOAD_COLOUR = "#d9541e";
const DRIVE_COLOUR = "#2a9d4b";

const $ = (id) => document.getElementById(id);
const form = $("design-form");
let openapi = null;
let presets = [];
let lastResult = null; // { rows, unavailable } of the current design
let lastBand = null; // the robustness band the shown results were designed with (null: none)
let lastPlant = null; // { gain, input, modes } of the plant the shown results were designed for
let selected = null; // the selected row
let userSelected = false; // the user chose a row: arriving rows do not take the plot over
let motionPlot = null;
let residualPlot = null;
let sensitivityPlot = null;
let tradeoffPlot = null;
let tradeoffRows = null;
let tradeoffKey = null; // tradeoffKeyOf() of the inputs the shown trade-off was computed for
let designSeq = 0;
let tradeoffSeq = 0;
let pending = new Map(); // job key -> { name, started, li }
let pendingTimer = null;

function numberOrNull(id) {
  const el = $(id);
  const text = el ? el.value.trim() : "";
  return text === "" ? null : Number(text);
}

// ------------------------------------------------------------------------------------------
// Numbers and units

// One format for every number on the page: 4 significant digits, fixed between 1e-3 and 1e4,
// else scientific (5.620e-15); exact zero as 0.
function fmt(value) {
  if (value === null || value === undefined) return "–";
  if (typeof value === "boolean") return value ? "yes" : "no";
  const x = Number(value);
  if (!Number.isFinite(x)) return String(x);
  if (x === 0) return "0";
  const a = Math.abs(x);
  if (a >= 1e-3 && a < 9999.5) return x.toPrecision(4);
  return x.toExponential(3).replace("e+", "e");
}

// A ratio or a percentage as typed, without trailing zeros: 0.9, 1.1, 0.8220, 5.
function plain(value, decimals = 4) {
  return String(Number(Number(value).toFixed(decimals)));
}

// The coordinate of the motor and the load: the plant kind says it (two-inertia and belt plants turn,
// Chatlatanagulchai's drive and load slide); a single mode is either, as the user says.
function coordinate() {
  const kind = $("plant-kind").value;
  if (kind === "mode") return $("coordinate").value;
  return kind === "rigid_flexible" ? "m" : "rad";
}

function unitsOf(unit) {
  return { position: unit, velocity: unit + "/s", acceleration: unit + "/s²", jerk: unit + "/s³" };
}

const PREFIXES = [[1e-15, "f"], [1e-12, "p"], [1e-9, "n"], [1e-6, "µ"], [1e-3, "m"], [1, ""], [1e3, "k"], [1e6, "M"]];

// The SI prefix that puts maxAbs in [1, 1000): { factor, unit }, e.g. 6.2e-6 m -> x 1e6, "µm".
function siScale(maxAbs, unit) {
  if (!(maxAbs > 0) || !Number.isFinite(maxAbs)) return { factor: 1, unit };
  let chosen = PREFIXES[0];
  for (const prefix of PREFIXES) if (maxAbs >= prefix[0] * (1 - 1e-12)) chosen = prefix;
  return { factor: 1 / chosen[0], unit: chosen[1] + unit };
}

// Tick labels with as many decimals as the tick step needs (0.25 -> 2; 5 -> 0), so that no two differ
// only beyond the shown digits.
function tickValues(u, splits) {
  if (splits.length < 2) return splits.map((v) => fmt(v));
  const step = Math.abs(splits[1] - splits[0]);
  let decimals = 0;
  while (decimals < 12 && Math.abs(Math.round(step * 10 ** decimals) - step * 10 ** decimals) > 1e-6 * step * 10 ** decimals) {
    decimals += 1;
  }
  return splits.map((v) => (Math.abs(v) < step * 1e-6 ? "0" : v.toFixed(decimals)));
}

function maxAbs(values) {
  let m = 0;
  for (const v of values) if (v !== null && Number.isFinite(v) && Math.abs(v) > m) m = Math.abs(v);
  return m;
}

function updateUnitLabels() {
  const units = unitsOf(coordinate());
  const velocityMove = form.elements.move.value === "target_velocity";
  $("move-label").textContent = velocityMove ? `Target velocity (${units.velocity})` : `Displacement (${units.position})`;
  $("max_velocity-label").textContent = `Max velocity (${units.velocity})`;
  $("max_acceleration-label").textContent = `Max acceleration (${units.acceleration})`;
  $("max_jerk-label").textContent = `Max jerk (${units.jerk})`;
  const set = (cls, text) => { for (const el of document.querySelectorAll(cls)) el.textContent = text; };
  set(".unit-motor", units.position);
  set(".unit-motor-v", units.velocity);
  set(".unit-motor-a", units.acceleration);
  set(".unit-motor-j", units.jerk);
  set(".unit-load-res", velocityMove ? units.velocity : units.position);
}

// ------------------------------------------------------------------------------------------
// The form: plant fields from the OpenAPI schemas, presets from the OpenAPI examples

function schemaOf(name) {
  return openapi && openapi.components && openapi.components.schemas ? openapi.components.schemas[name] : null;
}

// The paper's plant of each kind (the examples of POST /v1/plants/analyze): a kind's default values.
function plantExample(kind) {
  if (kind === "mode") return DEFAULT_MODE;
  const examples = examplesOf("/v1/plants/analyze");
  for (const example of Object.values(examples)) {
    const plant = example.value && example.value.plant;
    if (plant && plant.kind === kind) return plant;
  }
  return {};
}

function examplesOf(path) {
  const op = openapi && openapi.paths && openapi.paths[path] && openapi.paths[path].post;
  const content = op && op.requestBody && op.requestBody.content && op.requestBody.content["application/json"];
  return (content && content.examples) || {};
}

function renderPlantFields(kind, values) {
  const box = $("plant-fields");
  box.innerHTML = "";
  const schema = schemaOf(PLANT_SCHEMAS[kind]);
  if (!schema) return;
  for (const [key, prop] of Object.entries(schema.properties)) {
    if (key === "kind") continue;
    const id = "plant-" + key;
    const label = document.createElement("label");
    label.htmlFor = id;
    label.textContent = prop.description || prop.title || key;
    const input = document.createElement("input");
    Object.assign(input, { id, name: id, type: "number", step: "any" });
    input.dataset.field = "plant." + key;
    input.setAttribute("aria-describedby", "err-plant." + key);
    const value = values && values[key] !== undefined ? values[key] : prop.default;
    input.value = value === undefined || value === null ? "" : String(value);
    const error = document.createElement("p");
    error.className = "field-error";
    error.id = "err-plant." + key;
    error.setAttribute("role", "alert");
    box.append(label, input, error);
  }
}

function loadPresets() {
  presets = [];
  const select = $("preset");
  for (const [path, family] of Object.entries(ENDPOINT_FAMILY)) {
    const group = document.createElement("optgroup");
    group.label = family === "all" ? "Compare (POST /v1/compare)" : `${FAMILIES[family]} (POST ${path})`;
    for (const [key, example] of Object.entries(examplesOf(path))) {
      const value = example.value || {};
      const plant = value.plant;
      if (!plant || !PLANT_SCHEMAS[plant.kind]) continue;
      if (value.displacement === undefined && value.target_velocity === undefined) continue;
      const id = `${path}#${key}`;
      presets.push({ id, path, family, key, summary: example.summary || key, description: example.description || "", value });
      const option = document.createElement("option");
      option.value = id;
      option.textContent = example.summary || key;
      group.appendChild(option);
    }
    if (group.children.length) select.appendChild(group);
  }
}

function currentPreset() {
  return presets.find((p) => p.id === $("preset").value) || null;
}

// The endpoint's own options of an example (what the form does not show): sent with its row.
function presetExtras(preset) {
  if (!preset || preset.family === "all") return {};
  const extras = {};
  for (const [key, value] of Object.entries(preset.value)) {
    if (!FORM_KEYS.has(key)) extras[key] = value;
  }
  const robustness = preset.value.robustness;
  if (robustness && Object.keys(robustness).some((k) => k !== "frequency_ratio_range" && k !== "max_percentage_vibration")) {
    extras.robustness = robustness; // e.g. derivative_order: the form's band cannot say it
  }
  return extras;
}

function setValue(id, value) {
  $(id).value = value === undefined || value === null ? "" : String(value);
}

function applyPreset() {
  const preset = currentPreset();
  if (!preset) { $("preset-note").textContent = ""; return; }
  const v = preset.value;
  $("plant-kind").value = v.plant.kind;
  renderPlantFields(v.plant.kind, v.plant);
  if (v.plant.kind === "mode") {
    // A mode has no coordinate of its own: the example's text says it (150 rad/s, 0.12 m, 30 mm), else unchanged.
    for (const text of [preset.summary, preset.description]) {
      const rad = /\brad\b|rad\/s/.test(text);
      const metre = /\d\s*(m|mm|m\/s)\b/.test(text);
      if (rad !== metre) { $("coordinate").value = rad ? "rad" : "m"; break; }
    }
  }
  const velocityMove = v.target_velocity !== undefined;
  form.elements.move.value = velocityMove ? "target_velocity" : "displacement";
  setValue("move-value", velocityMove ? v.target_velocity : v.displacement);
  for (const name of LIMIT_NAMES) setValue(name, v.limits ? v.limits[name] : null);
  for (const name of ["duration_s", "sample_period_s", "horizon_s"]) setValue(name, v[name]);
  $("shaper").value = v.shaper && [...$("shaper").options].some((o) => o.value === v.shaper) ? v.shaper : "";
  const range = v.robustness && v.robustness.frequency_ratio_range;
  $("robustness").value = range ? "band" : "none";
  if (range) {
    setValue("band-percent", plain((range[1] - 1) * 100, 3));
    setValue("max-vibration", v.robustness.max_percentage_vibration ?? 5);
  }
  $("family").value = preset.family;
  const extras = presetExtras(preset);
  const options = Object.entries(extras).map(([k, value]) => `${k} = ${JSON.stringify(value)}`);
  $("preset-note").textContent = `${preset.summary}. ${preset.description ? preset.description + " " : ""}`
    + `From the example "${preset.key}" of POST ${preset.path}: its plant, move and limits fill the form.`
    + (options.length ? ` Its own options (${options.join(", ")}) are sent with the row "paper's example".` : "");
  syncForm();
  analysePlant();
}

// ------------------------------------------------------------------------------------------
// Requests

// Plant, move, limits and sampling: what every endpoint shares.
function buildCommon() {
  const kind = $("plant-kind").value;
  const plant = { kind };
  for (const input of $("plant-fields").querySelectorAll("input")) {
    const text = input.value.trim();
    if (text !== "") plant[input.dataset.field.slice("plant.".length)] = Number(text);
  }
  const moveKind = form.elements.move.value;
  const request = { plant };
  request[moveKind] = numberOrNull("move-value");
  const limits = {};
  for (const name of LIMIT_NAMES) {
    const value = numberOrNull(name);
    if (value !== null) limits[name] = value;
  }
  request.limits = limits;
  for (const name of ["sample_period_s", "horizon_s"]) {
    const value = numberOrNull(name);
    if (value !== null) request[name] = value;
  }
  const drive = buildDrive();
  // Designed for the loop: the plant is the closed loop from the command to the load (its modes are cancelled)
  if (drive && $("drive-design").checked) request.plant = { kind: "closed_loop", mechanics: plant, drive };
  else if (drive) request.drive = drive;
  return request;
}

// The API's drive by bandwidths (null without the checkbox): an empty position loop is a velocity-mode drive, an
// empty current loop an ideal torque.
function buildDrive() {
  if (!$("drive-on").checked) return null;
  const loop = (id) => { const hz = numberOrNull(id); return hz === null ? null : { bandwidth_hz: hz }; };
  const motor = {
    resistance_ohm: numberOrNull("drive-r"), inductance_h: numberOrNull("drive-l"),
    torque_constant_nm_per_a: numberOrNull("drive-kt"),
  };
  const inertia = numberOrNull("drive-inertia");
  if (inertia !== null) motor.inertia_kgm2 = inertia;
  return {
    sample_period_s: numberOrNull("drive-period"),
    position_loop: loop("drive-position"), velocity_loop: loop("drive-velocity") || {},
    current_loop: loop("drive-current"), motor,
  };
}

// The robustness control: null (none), or the band as the time-optimal endpoint takes it.
function readBand() {
  if ($("robustness").value !== "band") return null;
  const percent = numberOrNull("band-percent");
  const vmax = numberOrNull("max-vibration");
  const range = percent === null ? null : [1 - percent / 100, 1 + percent / 100];
  return { percent, vmax, robustness: { frequency_ratio_range: range, max_percentage_vibration: vmax } };
}

async function postJson(url, body) {
  const response = await fetch(url, {
    method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body),
  });
  let parsed = null;
  try { parsed = await response.json(); } catch (error) { parsed = { title: "Error", detail: String(error) }; }
  return { ok: response.ok, status: response.status, body: parsed };
}

// A profile endpoint's answer as a compare row (the endpoint answers in its own blocks).
function endpointRow(body, meta) {
  const m = body.metrics;
  const velocityMove = meta.request.target_velocity !== undefined && meta.request.target_velocity !== null;
  return {
    family: meta.family, label: meta.label, variantName: meta.variantName, endpoint: meta.endpoint,
    request: meta.request, motion_time_s: m.motion_time_s, settling_time_s: m.settling_time_s,
    settling_vibration_window: m.settling_vibration_window, percentage_vibration: m.percentage_vibration,
    residual_amplitude: velocityMove ? m.residual_velocity_amplitude : m.residual_amplitude,
    band_5_percent: body.sensitivity ? body.sensitivity.band_5_percent : null,
    peak_velocity: m.peak_velocity, peak_acceleration: m.peak_acceleration, peak_jerk: m.peak_jerk,
    peak_motor_torque_nm: m.peak_motor_torque_nm, limits_met: body.limits_met,
    warnings: body.warnings, design: body.design,
    curves: { profile: body.profile, load: body.load, sensitivity: body.sensitivity,
      closed_loop_load: body.closed_loop ? body.closed_loop.load : null },
    closed_loop: body.closed_loop ? {
      settling_time_s: body.closed_loop.metrics.settling_time_s, saturated: body.closed_loop.saturated,
    } : null,
  };
}

// The plant's modes and the gain that refers the motor to the load: G(0) of the command's transfer function
// (the load per unit motor position, or per unit drive velocity for a velocity-input plant).
function plantReference(analysis) {
  const tf = analysis.transfer_function;
  const num = tf.numerator[tf.numerator.length - 1];
  const den = tf.denominator[tf.denominator.length - 1];
  return { gain: den === 0 ? analysis.dc_gain : num / den, input: tf.input, modes: analysis.modes };
}

function describeModes(reference) {
  const modes = reference.modes.map((m, i) => `mode ${i + 1}: f_n = ${fmt(m.natural_frequency_hz)} Hz`
    + ` (ω_n = ${fmt(m.natural_frequency_rad_s)} rad/s), ζ = ${fmt(m.damping_ratio)}`);
  const gain = reference.input === "velocity" ? `load per unit drive velocity G(0) = ${fmt(reference.gain)} s`
    : `load per unit motor position G(0) = ${fmt(reference.gain)}`;
  $("plant-modes").textContent = `${modes.join("; ")}; ${gain}.`;
}

let analyseSeq = 0;
async function analysePlant() {
  const seq = ++analyseSeq;
  try {
    const answer = await postJson("/v1/plants/analyze", { plant: buildCommon().plant });
    if (seq !== analyseSeq) return;
    if (answer.ok) describeModes(plantReference(answer.body));
    else $("plant-modes").textContent = "";
  } catch (error) {
    if (seq === analyseSeq) $("plant-modes").textContent = "";
  }
}

// ------------------------------------------------------------------------------------------
// Errors

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
    // a closed_loop plant's mechanics and drive are the form's plant and drive fields
    const field = (error.field || "").replace(/^plant\.drive(?=$|\.)/, "drive").replace(/^plant\.mechanics(?=$|\.)/, "plant");
    const candidates = [...document.querySelectorAll("[data-field]")]
      .filter((el) => field === el.dataset.field || field.startsWith(el.dataset.field + ".") || field.startsWith(el.dataset.field + "["))
      .sort((a, b) => b.dataset.field.length - a.dataset.field.length);
    const target = candidates[0];
    const slot = target && $("err-" + target.dataset.field);
    if (slot) {
      slot.textContent = (context && !slot.textContent ? context : "") + (error.rule || problem.detail);
      target.setAttribute("aria-invalid", "true");
      placed = true;
    }
  }
  if (!placed) $("form-error").textContent = context + (problem.title || "Error") + ": " + problem.detail;
  const firstInvalid = document.querySelector("[aria-invalid=true]");
  if (firstInvalid) firstInvalid.focus();
}

// ------------------------------------------------------------------------------------------
// The table

function designName(row) {
  const family = FAMILIES[row.family] || row.family;
  if (row.variantName) return `${family}: ${row.variantName}`;
  const variant = (row.label || "").split("/")[1];
  const name = variant && shaperName(variant) !== variant.toUpperCase() ? shaperName(variant) : null;
  const shown = name || (variant && (isShaper(variant) ? variant.toUpperCase() : variant.replace(/_/g, " ")));
  return shown ? `${family}: ${shown}` : family;
}

function isShaper(name) {
  return /^zv(d*)$|^mzv$|^ei$|^\dhump_ei$/.test(name);
}

function shaperName(name) {
  const hump = /^(\d)hump_ei$/.exec(name);
  return hump ? `${hump[1]}-hump EI` : name.toUpperCase();
}

function bandText(band) {
  if (!band) return "–";
  const [low, high] = band;
  return `${low === null ? "below 0.5" : fmt(low)} – ${high === null ? "above 1.5" : fmt(high)}`;
}

function renderTable() {
  const body = $("compare-table").querySelector("tbody");
  body.innerHTML = "";
  const rows = lastResult ? lastResult.rows : [];
  rows.forEach((row, index) => {
    const tr = document.createElement("tr");
    tr.tabIndex = 0;
    tr.dataset.index = String(index);
    tr.setAttribute("aria-selected", String(row === selected));
    tr.dataset.label = row.label || row.family;
    const cells = [
      designName(row), fmt(row.motion_time_s), fmt(row.settling_time_s), throughDrive(row), fmt(row.percentage_vibration),
      fmt(row.residual_amplitude), bandText(row.band_5_percent), fmt(row.peak_velocity), fmt(row.peak_acceleration),
      fmt(row.peak_jerk), fmt(row.peak_motor_torque_nm), fmt(row.limits_met),
    ];
    cells.forEach((text, i) => {
      const td = document.createElement("td");
      td.textContent = text;
      if (i === 0) td.style.borderLeft = `4px solid ${PALETTE[index % PALETTE.length]}`;
      tr.appendChild(td);
    });
    const choose = () => { userSelected = true; selectRow(row); };
    tr.addEventListener("click", choose);
    tr.addEventListener("keydown", (event) => {
      if (event.key === "Enter" || event.key === " ") { event.preventDefault(); choose(); }
    });
    body.appendChild(tr);
  });
  const list = $("unavailable");
  list.innerHTML = "";
  for (const item of lastResult ? lastResult.unavailable : []) {
    const li = document.createElement("li");
    li.textContent = `${item.name || FAMILIES[item.family] || item.family}: ${item.reason}`;
    list.appendChild(li);
  }
}

// The settling through the drive, and whether the command drives the motor past a limit there.
function throughDrive(row) {
  if (!row.closed_loop) return "–";
  return fmt(row.closed_loop.settling_time_s) + (row.closed_loop.saturated ? " (saturates)" : "");
}

// Compare's order: settling time (never-settling last; through the drive where there is one), then motion time.
function insertSorted(rows, row) {
  const settling = (r) => (r.closed_loop ? r.closed_loop.settling_time_s : r.settling_time_s);
  const key = (r) => [settling(r) === null ? Infinity : settling(r), r.motion_time_s];
  const [s, t] = key(row);
  let index = rows.findIndex((r) => { const [rs, rt] = key(r); return rs > s || (rs === s && rt > t); });
  if (index < 0) index = rows.length;
  rows.splice(index, 0, row);
  return index;
}

function selectRow(row) {
  selected = row;
  for (const tr of $("compare-table").querySelectorAll("tbody tr")) {
    const index = Number(tr.dataset.index);
    tr.setAttribute("aria-selected", String(lastResult !== null && lastResult.rows[index] === row));
  }
  $("csv-button").disabled = !row;
  drawMotion();
  drawResidual();
  drawSensitivity();
}

// Until the user picks a row: the robust design, else the paper's example, else the best so far.
function autoSelect() {
  if (userSelected && selected && lastResult.rows.includes(selected)) { selectRow(selected); return; }
  const rows = lastResult.rows;
  const preferred = rows.find((r) => r.preference === 2) || rows.find((r) => r.preference === 1) || rows[0] || null;
  selectRow(preferred);
}

// ------------------------------------------------------------------------------------------
// Plots

function plotWidth(el) {
  return Math.max(320, Math.min(el.clientWidth || 800, 1100));
}

function destroy(plot) {
  if (plot) plot.destroy();
  return null;
}

const DERIVATIVE = { position: "velocity", velocity: "acceleration", acceleration: "jerk" };

// The motor as the load would follow it if the plant were rigid: G(0) times the command input (the
// motor's quantity for position input; for a velocity input, the drive's next derivative).
// A closed-loop series on the profile's times: the drive's own where they are the same (a continuous drive), else
// linearly interpolated between its samples for drawing (a sampled drive; a run past the end at a limit), null
// outside them.
function onProfileTimes(time, closedTime, values) {
  if (!closedTime || (closedTime.length === time.length && closedTime[0] === time[0]
      && closedTime[closedTime.length - 1] === time[time.length - 1])) return values;
  if (closedTime.length < 2) return time.map((t) => (t === closedTime[0] ? values[0] : null));
  let j = 0;
  return time.map((t) => {
    if (t < closedTime[0] || t > closedTime[closedTime.length - 1]) return null;
    while (j < closedTime.length - 2 && closedTime[j + 1] < t) j += 1;
    const span = closedTime[j + 1] - closedTime[j];
    const w = span > 0 ? (t - closedTime[j]) / span : 0;
    return values[j] + w * (values[j + 1] - values[j]);
  });
}

function motorReferred(profile, quantity) {
  const { gain, input } = lastPlant;
  const source = input === "velocity" ? profile[DERIVATIVE[quantity]] : profile[quantity];
  return source.map((v) => v * gain);
}

function drawMotion() {
  const el = $("motion-plot");
  motionPlot = destroy(motionPlot);
  $("motion-note").textContent = "";
  const row = selected;
  if (!row || !row.curves || !lastPlant) { $("plot-title").textContent = "Motor and load"; return; }
  const quantity = $("quantity").value;
  const { profile, load } = row.curves;
  const motor = motorReferred(profile, quantity);
  const loadValues = load[quantity];
  const baseUnit = unitsOf(coordinate())[quantity];
  const scale = siScale(Math.max(maxAbs(motor), maxAbs(loadValues)), baseUnit);
  const gain = lastPlant.gain;
  const velocityInput = lastPlant.input === "velocity";
  const motorLabel = velocityInput ? `G(0) × drive ${DERIVATIVE[quantity]}`
    : Math.abs(gain - 1) < 1e-12 ? `motor ${quantity}` : `motor ${quantity} × G(0)`;
  $("plot-title").textContent = `Motor and load: ${designName(row)}`;
  const closed = row.curves.closed_loop_load && row.curves.closed_loop_load[quantity] ? row.curves.closed_loop_load : null;
  const designedThrough = row.closed_loop && row.closed_loop.designedThrough;
  const ideal = closed ? ", ideal motor" : designedThrough ? ", through the drive" : "";
  const series = [{ label: "t (s)" },
    { label: `${motorLabel} (${scale.unit})`, stroke: MOTOR_COLOUR, width: 2 },
    { label: `load ${quantity}${ideal} (${scale.unit})`, stroke: LOAD_COLOUR, width: 2 }];
  const data = [profile.time_s, motor.map((v) => v * scale.factor), loadValues.map((v) => v * scale.factor)];
  if (closed) {
    series.push({ label: `load ${quantity}, through the drive (${scale.unit})`, stroke: DRIVE_COLOUR, width: 2, dash: [6, 4] });
    data.push(onProfileTimes(profile.time_s, closed.time_s, closed[quantity]).map((v) => (v === null ? null : v * scale.factor)));
  }
  motionPlot = new uPlot({
    width: plotWidth(el), height: 280,
    legend: { live: false },
    scales: { x: { time: false } },
    axes: [{ label: "time (s)", values: tickValues }, { label: `${quantity} (${scale.unit})`, values: tickValues, size: 60 }],
    series,
  }, data, el);
  motionPlot.unitScale = scale;
  if (!velocityInput && Math.abs(gain - 1) >= 1e-12) {
    $("motion-note").textContent = `The motor is drawn referred to the load: times G(0) = ${fmt(gain)}, the load's `
      + "motion if the plant were rigid.";
  } else if (velocityInput) {
    $("motion-note").textContent = `A velocity-input plant: the load follows G(0) = ${fmt(gain)} s times the drive `
      + `${DERIVATIVE[quantity]} when rigid.`;
  }
}

// Load minus its rigid target (the deflection where the API gives it), from the command's end on.
function residualOf(row) {
  const { profile, load } = row.curves;
  if (load.deflection) return load.deflection;
  const reference = motorReferred(profile, "position");
  return load.position.map((v, i) => v - reference[i]);
}

function drawResidual() {
  const el = $("residual-plot");
  residualPlot = destroy(residualPlot);
  $("residual-note").textContent = "";
  const row = selected;
  if (!row || !row.curves || !lastPlant) return;
  const time = row.curves.profile.time_s;
  const residual = residualOf(row);
  const end = row.motion_time_s + time[0];
  // Strictly after the end: the sample at the end itself can carry the move's last value.
  let first = time.findIndex((t) => t > end + 1e-9 * Math.max(1, Math.abs(end)));
  if (first < 0 || time.length - first < 5) first = 0; // no samples after the command: show it all
  const t = time.slice(first);
  const r = residual.slice(first);
  // Through the drive (with one): its load less the same rigid target.
  const closedLoad = row.curves.closed_loop_load;
  const reference = motorReferred(row.curves.profile, "position");
  const c = closedLoad
    ? onProfileTimes(time, closedLoad.time_s, closedLoad.position).map((v, i) => (v === null ? null : v - reference[i])).slice(first)
    : null;
  const peak = Math.max(maxAbs(r), c ? maxAbs(c) : 0);
  const scale = siScale(peak, coordinate());
  const half = peak > 0 ? peak * scale.factor * 1.15 : 1;
  const through = row.closed_loop && row.closed_loop.designedThrough ? ", through the drive" : "";
  const series = [{ label: "t (s)" }, { label: `load − rigid target${c ? ", ideal motor" : through} (${scale.unit})`, stroke: LOAD_COLOUR, width: 1.5 }];
  const data = [t, r.map((v) => v * scale.factor)];
  if (c) {
    series.push({ label: `through the drive (${scale.unit})`, stroke: DRIVE_COLOUR, width: 1.5, dash: [6, 4] });
    data.push(c.map((v) => (v === null ? null : v * scale.factor)));
  }
  residualPlot = new uPlot({
    width: plotWidth(el), height: 220,
    legend: { live: false },
    scales: { x: { time: false }, y: { range: [-half, half] } },
    axes: [{ label: "time (s)", values: tickValues }, { label: `load − target (${scale.unit})`, values: tickValues, size: 70 }],
    series,
  }, data, el);
  residualPlot.unitScale = scale;
  const window = row.settling_vibration_window;
  $("residual-title").textContent = `Residual vibration after the move: ${designName(row)}`;
  const tiny = peak > 0 && peak < 1e-12 * Math.max(1, maxAbs(row.curves.load.position));
  $("residual-note").textContent = `Zoomed to t ≥ ${fmt(t[0])} s, after the command ends: `
    + (peak === 0 ? "the load is exactly at its target (no residual to plot)."
      : `peak |load − rigid target| ${fmt(peak * scale.factor)} ${scale.unit}${tiny ? ": rounding noise, no residual" : ""}.`)
    + (window ? ` Settling needs the vibration envelope below ${fmt(window)} ${coordinate()}.` : "");
}

function drawSensitivity() {
  const el = $("sensitivity-plot");
  sensitivityPlot = destroy(sensitivityPlot);
  $("sensitivity-note").textContent = "";
  $("sensitivity-legend").textContent = "";
  const rows = (lastResult ? lastResult.rows : []).filter((r) => r.curves && r.curves.sensitivity);
  if (!rows.length) return;
  const x = rows[0].curves.sensitivity.frequency_ratio;
  const shown = rows.filter((r) => r.curves.sensitivity.frequency_ratio.length === x.length);
  let top = 10;
  for (const row of shown) top = Math.max(top, maxAbs(row.curves.sensitivity.percentage_vibration));
  const clipped = top > 100;
  top = Math.min(100, top * 1.05);
  const series = [{ label: "fn / fn,e" }];
  const data = [x];
  for (const row of shown) {
    const index = lastResult.rows.indexOf(row);
    const chosen = row === selected;
    series.push({ label: designName(row), stroke: PALETTE[index % PALETTE.length], width: chosen ? 3 : 1.25 });
    data.push(row.curves.sensitivity.percentage_vibration);
  }
  series.push({ label: "5 % line", stroke: "#b3261e", width: 1.5, dash: [6, 4] });
  data.push(x.map(() => 5));
  const achieved = selected ? achievedBand(selected) : null;
  sensitivityPlot = new uPlot({
    width: plotWidth(el), height: 300,
    legend: { live: false },
    scales: { x: { time: false }, y: { range: [0, top] } },
    axes: [{ label: "fn / fn,e (true over design natural frequency)", values: tickValues },
      { label: "percentage vibration V (%)", values: tickValues }],
    series,
    hooks: { draw: [(u) => drawBandMarks(u, lastBand, achieved)] },
  }, data, el);
  $("sensitivity-legend").textContent = `Every design's V (the residual over the unshaped rigid command's, %); `
    + `the selected one (${selected ? designName(selected) : "none"}) drawn thick; dashed red: V = 5 %; `
    + "vertical line: ratio 1, the design frequency."
    + (clipped ? " The V axis stops at 100 %: a curve above it leaves more vibration than the unshaped command." : "");
  if (selected) describeBands(selected, achieved);
}

function achievedBand(row) {
  const robustness = row.design && row.design.robustness;
  return (robustness && robustness.achieved && robustness.achieved.frequency_ratio_range) || null;
}

// Ratio 1, the requested band (shaded, with its V max as a dotted line) and the achieved one (two dashed
// lines), as elements over the plot's canvas, placed in the plot's own coordinates on every redraw.
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
  if (xMin <= 1 && xMax >= 1) {
    const one = mark("ratio-one", { left: x(1) + "px" }, "ratio 1: the design frequency");
    one.textContent = "ratio 1";
  }
  if (band && band.robustness.frequency_ratio_range) {
    const [low, high] = band.robustness.frequency_ratio_range;
    const el = mark("band-requested", { left: x(low) + "px", width: Math.max(1, x(high) - x(low)) + "px" },
      `requested band ${fmt(low)} – ${fmt(high)}`);
    el.dataset.low = String(low);
    el.dataset.high = String(high);
    const v = band.vmax;
    if (v !== null && v >= u.scales.y.min && v <= u.scales.y.max) {
      mark("band-vmax", { top: u.valToPos(v, "y") + "px" }, `V max ${fmt(v)} %`);
    }
  }
  if (achieved) {
    const [low, high] = achieved;
    for (const [value, side] of [[low, "low"], [high, "high"]]) {
      if (value === null || value < xMin || value > xMax) continue; // the achieved band runs past the plotted ratios
      const el = mark("band-achieved band-achieved-" + side, { left: x(value) + "px" },
        `achieved band ${side} end ${fmt(value)}`);
      el.dataset.value = String(value);
    }
  }
}

function describeBands(row, achieved) {
  const parts = [];
  if (lastBand && lastBand.robustness.frequency_ratio_range) {
    const [low, high] = lastBand.robustness.frequency_ratio_range;
    parts.push(`Shaded: the requested band ${plain(low)} – ${plain(high)}; dotted line: its V max ${plain(lastBand.vmax, 3)} %.`);
  }
  if (achieved) {
    parts.push(`Purple dashed lines: the band ${plain(achieved[0], 3)} – ${plain(achieved[1], 3)} achieved by ${designName(row)}.`);
  }
  $("sensitivity-note").textContent = parts.join(" ");
}

// ------------------------------------------------------------------------------------------
// Design: fast rows first, the solver rows as they arrive

function clearResults() {
  lastResult = null;
  lastBand = null;
  lastPlant = null;
  selected = null;
  stopPending();
  $("compare-table").querySelector("tbody").innerHTML = "";
  $("unavailable").innerHTML = "";
  $("residual-title").textContent = "Residual vibration after the move";
  $("plant-modes").textContent = "";
  selectRow(null);
}

function stopPending() {
  pending = new Map();
  $("pending").innerHTML = "";
  $("design-progress").hidden = true;
  form.removeAttribute("aria-busy");
  if (pendingTimer) { clearInterval(pendingTimer); pendingTimer = null; }
}

function tickPending() {
  const now = performance.now();
  for (const job of pending.values()) {
    job.text.textContent = `${job.name}: designing… ${((now - job.started) / 1000).toFixed(1)} s`;
  }
}

function startPending(key, name) {
  const li = document.createElement("li");
  li.dataset.job = key;
  const bar = document.createElement("progress");
  bar.setAttribute("aria-label", `Designing ${name}`);
  const text = document.createElement("span");
  li.append(bar, text);
  $("pending").appendChild(li);
  pending.set(key, { name, started: performance.now(), li, text });
  $("design-progress").hidden = false;
  form.setAttribute("aria-busy", "true");
  tickPending();
  if (!pendingTimer) pendingTimer = setInterval(tickPending, 100);
}

function endPending(key) {
  const job = pending.get(key);
  if (job) job.li.remove();
  pending.delete(key);
  if (!pending.size) stopPending();
}

// What one Design sends: { key, name, phase, send() -> { rows, unavailable } or a problem }.
function planJobs(common, band) {
  const family = $("family").value;
  const wanted = family === "all" ? Object.keys(FAMILIES) : [family];
  const shaper = $("shaper").value;
  const jobs = [];
  const compareJob = (families, phase, name) => ({
    key: "compare:" + families.join(","), name, phase, fatal: true,
    send: async () => {
      const request = { ...common, include_curves: true, sensitivity: { ...SENSITIVITY }, families };
      const duration = numberOrNull("duration_s");
      if (duration !== null) request.duration_s = duration;
      const answer = await postJson("/v1/compare", request);
      return answer.ok ? { rows: answer.body.rows, unavailable: answer.body.unavailable } : { problem: answer.body };
    },
  });
  const endpointJob = (key, name, phase, endpoint, request, meta) => ({
    key, name, phase, fatal: false,
    send: async () => {
      const answer = await postJson(endpoint, request);
      if (!answer.ok) return { problem: answer.body };
      return { rows: [{ ...endpointRow(answer.body, { ...meta, endpoint, request }), preference: meta.preference || 0 }] };
    },
  });
  const fast = wanted.filter((f) => FAST_FAMILIES.includes(f) && !(f === "input_shaped" && shaper));
  // One compare per family: the quickest (STAP's closed form, about 0.1 s) is plotted while the others run.
  for (const f of fast) jobs.push(compareJob([f], 1, FAMILIES[f]));
  if (shaper && wanted.includes("input_shaped")) {
    const request = { ...common, shaper, sensitivity: { ...SENSITIVITY } };
    jobs.push(endpointJob("shaper", `Input shaping: ${shaperName(shaper)}`, 1, "/v1/profiles/input-shaped", request,
      { family: "input_shaped", label: `input_shaped/${shaper}`, variantName: shaperName(shaper) }));
  }
  for (const f of wanted.filter((name) => SLOW_FAMILIES.includes(name))) jobs.push(compareJob([f], 2, FAMILIES[f]));
  if (band !== null && wanted.includes("time_optimal")) {
    const request = { ...common, robustness: band.robustness, sensitivity: { ...SENSITIVITY } };
    jobs.push(endpointJob("robust", `Time-optimal: robust ±${band.percent} %`, 2, TIME_OPTIMAL_ENDPOINT, request,
      { family: "time_optimal", label: "time_optimal robust", variantName: `robust ±${band.percent} %`, preference: 2, band }));
  }
  const preset = currentPreset();
  const extras = presetExtras(preset);
  if (preset && Object.keys(extras).length) {
    const request = { ...extras, ...common, sensitivity: { ...SENSITIVITY } };
    if (preset.family === "pseudo_polynomial" && numberOrNull("duration_s") !== null) request.duration_s = numberOrNull("duration_s");
    if (preset.family === "input_shaped" && shaper) request.shaper = shaper;
    const name = `${FAMILIES[preset.family]}: paper's example (${preset.key})`;
    jobs.push(endpointJob("preset", name, 2, preset.path, request,
      { family: preset.family, label: `${preset.family}/paper ${preset.key}`, variantName: `paper's example (${preset.key})`, preference: 1 }));
  }
  return jobs;
}

async function design(event) {
  event.preventDefault();
  const seq = ++designSeq;
  performance.mark("vibfree:design-start");
  clearErrors();
  clearResults();
  userSelected = false;
  const started = performance.now();
  const common = buildCommon();
  const band = readBand();
  if (tradeoffKey !== null && tradeoffKey !== tradeoffKeyOf(band)) {
    clearTradeoff("The inputs changed: press Trade-off again.");
  }
  const jobs = planJobs(common, band);
  const current = () => seq === designSeq;
  let failed = false;
  let plotted = false;
  const results = { rows: [], unavailable: [] };
  $("design-button").disabled = true;
  $("status").textContent = "Designing…";

  const fail = (problem, context) => {
    failed = true;
    clearResults();
    showProblem(problem, context);
    $("status").textContent = "No design: fix the input marked above.";
  };
  const accept = (job, outcome) => {
    if (!current() || failed) return;
    endPending(job.key);
    if (outcome.problem) {
      // A compare refused for its input ends the design; one the service's state ended (503 busy or not ready,
      // 504 a solve out of time) is that family's reason, like an endpoint's.
      if (job.fatal && !(outcome.problem.status >= 500)) { fail(outcome.problem, ""); return; }
      showProblem(outcome.problem, `${job.name}: `);
      results.unavailable.push({ name: job.name, reason: outcome.problem.detail || outcome.problem.title });
    } else {
      for (const row of outcome.rows) {
        if (row.preference === 2) lastBand = band;
        // designed for the closed loop: the row's own load is the load through the drive
        if (common.plant.kind === "closed_loop" && !row.closed_loop) {
          row.closed_loop = { settling_time_s: row.settling_time_s, saturated: false, designedThrough: true };
        }
        insertSorted(results.rows, row);
      }
      results.unavailable.push(...(outcome.unavailable || []));
    }
    lastResult = results;
    renderTable();
    autoSelect();
    if (!plotted && selected) {
      plotted = true;
      performance.mark("vibfree:first-plot");
    }
    const waiting = [...pending.values()].map((j) => j.name);
    const seconds = ((performance.now() - started) / 1000).toFixed(1);
    $("status").textContent = waiting.length
      ? `${results.rows.length} design(s) so far; ${waiting.length} still running.`
      : results.rows.length ? `${results.rows.length} design(s) in ${seconds} s.` : "No family could meet the limits.";
  };
  const launch = (job) => {
    startPending(job.key, job.name);
    return job.send().catch((error) => ({ problem: { title: "The service did not answer", detail: String(error) } }));
  };

  try {
    const analysing = postJson("/v1/plants/analyze", { plant: common.plant });
    // The closed forms first (they run in the HTTP process); the solver jobs once they are in, so that a
    // fast family never waits behind a search on the worker pool.
    const first = jobs.filter((j) => j.phase === 1).map((job) => ({ job, outcome: launch(job) }));
    const analysis = await analysing;
    if (!current()) return;
    if (!analysis.ok) { fail(analysis.body, ""); return; }
    lastPlant = plantReference(analysis.body);
    describeModes(lastPlant);
    await Promise.all(first.map(async ({ job, outcome }) => accept(job, await outcome)));
    if (!current() || failed) return;
    $("design-button").disabled = false;
    await Promise.all(jobs.filter((j) => j.phase === 2).map(async (job) => accept(job, await launch(job))));
  } catch (error) {
    if (current()) fail({ title: "The service did not answer", detail: String(error) }, "");
  } finally {
    if (current()) $("design-button").disabled = false;
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
    legend: { live: false },
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
      row.duration_s === null ? "–" : fmt(row.duration_s * 1000),
      row.lower_bound_s === null ? "–" : fmt(row.lower_bound_s * 1000),
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

// The CSV is the row's endpoint answering the row's request again: a solver row takes as long as its design,
// so the button shows a progress bar while it runs.
async function downloadCsv() {
  const row = selected;
  if (!row) return;
  const button = $("csv-button");
  const bar = $("design-progress");
  button.disabled = true;
  const timer = setTimeout(() => { bar.hidden = false; $("status").textContent = `Preparing the CSV of ${designName(row)}…`; }, 300);
  try {
    const response = await fetch(row.endpoint + "?format=csv", {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(row.request),
    });
    if (!response.ok) { showProblem(await response.json(), "CSV: "); return; }
    const blob = await response.blob();
    const link = document.createElement("a");
    link.href = URL.createObjectURL(blob);
    link.download = `${(row.label || row.family).replace(/[/ ]/g, "-")}-profile.csv`;
    document.body.appendChild(link);
    link.click();
    link.remove();
    if (!bar.hidden) $("status").textContent = `CSV of ${designName(row)} downloaded.`;
  } catch (error) {
    $("form-error").textContent = "The service did not answer: " + error;
  } finally {
    clearTimeout(timer);
    if (!pending.size) bar.hidden = true;
    button.disabled = !selected;
  }
}

function syncForm() {
  $("coordinate-field").hidden = $("plant-kind").value !== "mode";
  $("drive-design-note").hidden = !$("drive-design").checked;
  const velocity = form.elements.move.value === "target_velocity";
  $("move-value").dataset.field = velocity ? "target_velocity" : "displacement";
  $("band-fields").hidden = $("robustness").value !== "band";
  $("drive-inputs").hidden = !$("drive-on").checked;
  updateUnitLabels();
}

async function loadShapers() {
  try {
    const response = await fetch("/v1/shapers");
    if (!response.ok) throw new Error(`GET /v1/shapers answered ${response.status}`);
    const catalogue = await response.json();
    for (const shaper of catalogue.shapers) {
      const option = document.createElement("option");
      option.value = shaper.name;
      option.textContent = `${shaperName(shaper.name)}: ${shaper.impulse_count} impulses over ${fmt(shaper.duration_periods)} `
        + `period(s), 5 % band ${bandText(shaper.band_5_percent)} (undamped)`;
      $("shaper").appendChild(option);
    }
  } catch (error) {
    $("err-shaper").textContent = "The shaper catalogue did not load: " + error;
  }
}

async function init() {
  try {
    const response = await fetch("/openapi.json");
    openapi = await response.json();
  } catch (error) {
    $("form-error").textContent = "The form's schema (/openapi.json) did not load: " + error;
    return;
  }
  loadPresets();
  // the kind shown now (chosen, or restored by the browser, before the schema loaded): its fields
  renderPlantFields($("plant-kind").value, plantExample($("plant-kind").value));
  await loadShapers();
  syncForm();
  $("design-button").disabled = false;
}

for (const [value, label] of Object.entries(FAMILIES)) {
  const option = document.createElement("option");
  option.value = value;
  option.textContent = label;
  $("family").appendChild(option);
}
$("preset").addEventListener("change", applyPreset);
$("plant-kind").addEventListener("change", () => {
  renderPlantFields($("plant-kind").value, plantExample($("plant-kind").value));
  syncForm();
  analysePlant();
});
$("coordinate").addEventListener("change", () => { syncForm(); drawMotion(); drawResidual(); });
$("robustness").addEventListener("change", syncForm);
$("drive-on").addEventListener("change", syncForm);
$("drive-design").addEventListener("change", () => { syncForm(); analysePlant(); });
// designed for the loop, the modes shown are the loop's: they follow the drive's fields
$("drive-on").addEventListener("change", () => { if ($("drive-design").checked) analysePlant(); });
$("drive-inputs").addEventListener("change", (event) => {
  if (event.target.id !== "drive-design" && $("drive-design").checked && $("drive-on").checked) analysePlant();
});
$("tradeoff-button").addEventListener("click", computeTradeoff);
for (const radio of form.elements.move) radio.addEventListener("change", syncForm);
$("quantity").addEventListener("change", drawMotion);
$("csv-button").addEventListener("click", downloadCsv);
form.addEventListener("submit", design);
window.addEventListener("resize", () => { drawMotion(); drawResidual(); drawSensitivity(); drawTradeoff(); });
init();
