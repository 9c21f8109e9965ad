// The printer page: an accelerometer file to the firmware's input shaper (POST /v1/identify with text/csv and a
// target). No framework, no build step: uPlot draws the spectrum.
"use strict";

const $ = (id) => document.getElementById(id);
const PSD_COLOUR = "#57606a";
const OURS_COLOUR = "#1f6fb4";
const KLIPPER_COLOUR = "#c2410c";
let spectrumPlot = null;
let lastText = "";

function fixed(value, digits) {
  return value === null || value === undefined || !Number.isFinite(value) ? "-" : value.toFixed(digits);
}

function clearErrors() {
  document.querySelectorAll(".field-error, .form-error").forEach((el) => { el.textContent = ""; });
  document.querySelectorAll("[aria-invalid=true]").forEach((el) => el.removeAttribute("aria-invalid"));
}

// Each problem+json error next to the field it names (the query's names are the inputs' data-field), else above.
function showProblem(problem) {
  const errors = problem.errors && problem.errors.length ? problem.errors : [{ field: problem.field, rule: problem.detail }];
  for (const error of errors) {
    const field = String(error.field || "");
    const input = document.querySelector(`[data-field="${field}"]`);
    const slot = input ? $("err-" + field) : null;
    const text = `${field ? field + ": " : ""}${error.rule || problem.detail}`;
    if (slot) {
      slot.textContent = text;
      input.setAttribute("aria-invalid", "true");
    } else if (field.startsWith("body") || /^[a-z_]+\[\d+\]$/i.test(field) || field === "header") {
      $("err-body").textContent = text;  // a cell or a row of the file
      $("record").setAttribute("aria-invalid", "true");
    } else {
      $("form-error").textContent = text;
    }
  }
}

function query() {
  const params = new URLSearchParams({ target: $("target").value });
  const scv = $("scv").value.trim();
  if (scv !== "") params.set("square_corner_velocity", scv);
  const smoothing = $("max-smoothing").value.trim();
  if (smoothing !== "") params.set("max_smoothing", smoothing);
  const tolerance = $("tolerance").value.trim();
  if (tolerance !== "") params.set("frequency_tolerance", String(Number(tolerance) / 100));
  const test = { "sweep-min": "sweep_min_freq", "sweep-max": "sweep_max_freq", "sweep-rate": "sweep_hz_per_sec",
    "sweeping-period": "sweeping_period" };
  for (const [id, name] of Object.entries(test)) {
    const value = $(id).value.trim();
    if (value !== "") params.set(name, value);
  }
  return params;
}

async function analyse(event) {
  event.preventDefault();
  clearErrors();
  const file = $("record").files[0];
  if (!file && !lastText) {
    $("err-body").textContent = "Choose a CSV file: an accelerometer record or a resonance CSV.";
    return;
  }
  const text = file ? await file.text() : lastText;
  lastText = text;
  $("analyse-button").disabled = true;
  $("analyse-progress").hidden = false;
  $("status").textContent = "Analysing…";
  try {
    const response = await fetch("/v1/identify?" + query(), {
      method: "POST", headers: { "content-type": "text/csv" }, body: text,
    });
    const body = await response.json();
    if (!response.ok) {
      showProblem(body);
      $("status").textContent = `Not analysed (${response.status}).`;
      return;
    }
    show(body);
    $("status").textContent = "";
  } catch (error) {
    $("form-error").textContent = "The service did not answer: " + error;
    $("status").textContent = "";
  } finally {
    $("analyse-button").disabled = false;
    $("analyse-progress").hidden = true;
  }
}

function settingText(recommendation) {
  const blocks = recommendation.firmware;
  const target = recommendation.target;
  if (target === "klipper") return blocks.klipper.section.trimEnd();
  const block = blocks[target];
  return block ? block.command : `No ${target} setting: ${blocks[target + "_reason"]}`;
}

function row(label, values) {
  const tr = document.createElement("tr");
  const th = document.createElement("th");
  th.scope = "row";
  th.textContent = label;
  tr.appendChild(th);
  for (const value of values) {
    const td = document.createElement("td");
    td.textContent = value;
    tr.appendChild(td);
  }
  return tr;
}

function digits(width, least) {
  // decimals enough for an interval of this width to show (two significant digits of it), at least `least`
  if (!(width > 0)) return least;
  return Math.max(least, Math.min(6, Math.ceil(-Math.log10(width)) + 1));
}

function show(body) {
  const recommendation = body.recommendation;
  $("printer-results").hidden = false;
  $("firmware-text").textContent = settingText(recommendation);
  $("setting-reason").textContent = recommendation.reason;
  const tbody = $("shaper-table").querySelector("tbody");
  tbody.replaceChildren();
  const klipper = recommendation.klipper_calibration;
  tbody.appendChild(row("Recommended", [recommendation.shaper.type, fixed(recommendation.shaper.frequency_hz, 1),
    fixed(recommendation.remaining_vibration_percent, 2), fixed(recommendation.robust_remaining_vibration_percent, 2),
    fixed(recommendation.max_acceleration, 0), fixed(recommendation.smoothing, 3)]));
  tbody.appendChild(row("Klipper's calibration", [klipper.type, fixed(klipper.frequency_hz, 1),
    fixed(klipper.remaining_vibration_percent, 2), "", fixed(klipper.max_acceleration, 0), fixed(klipper.smoothing, 3)]));
  const resonances = $("resonances");
  resonances.replaceChildren();
  for (const mode of body.modes || []) {
    const li = document.createElement("li");
    const [lo, hi] = mode.natural_frequency_ci_hz;
    const [zlo, zhi] = mode.damping_ratio_ci;
    const f = digits(hi - lo, 2);
    const z = digits(zhi - zlo, 4);
    li.textContent = `${fixed(mode.natural_frequency_hz, f)} Hz (95 %: ${fixed(lo, f)} to ${fixed(hi, f)} Hz), `
      + `damping ratio ${fixed(mode.damping_ratio, z)} (95 %: ${fixed(zlo, z)} to ${fixed(zhi, z)})`;
    resonances.appendChild(li);
  }
  for (const peak of (body.modes || []).length ? [] : body.peaks || []) {
    const li = document.createElement("li");
    li.textContent = `${fixed(peak.frequency_hz, 1)} Hz peak, damping ratio about `
      + `${fixed(peak.damping_ratio_half_power, 3)} (half-power width)`;
    resonances.appendChild(li);
  }
  const warnings = $("warnings");
  warnings.replaceChildren(...(body.warnings || []).map((w) => {
    const li = document.createElement("li");
    li.textContent = w;
    return li;
  }));
  drawSpectrum(recommendation);
}

function drawSpectrum(recommendation) {
  const el = $("spectrum-plot");
  if (spectrumPlot) spectrumPlot.destroy();
  const r = recommendation.response;
  const ours = `${recommendation.shaper.type} ${fixed(recommendation.shaper.frequency_hz, 1)} Hz (recommended)`;
  const klipper = recommendation.klipper_calibration;
  const theirs = `${klipper.type} ${fixed(klipper.frequency_hz, 1)} Hz (Klipper's calibration)`;
  spectrumPlot = new uPlot({
    width: Math.max(320, Math.min(el.clientWidth || 800, 1100)), height: 300,
    scales: { x: { time: false }, v: { range: [0, 1] } },
    axes: [{ label: "frequency (Hz)" }, { label: "PSD, normalised ((mm/s²)²/Hz²)", size: 70 },
      { scale: "v", side: 1, label: "remaining share V", grid: { show: false } }],
    series: [{ label: "f (Hz)" },
      { label: "measured PSD", stroke: PSD_COLOUR, width: 2, fill: "rgba(87, 96, 106, 0.12)" },
      { label: ours, stroke: OURS_COLOUR, width: 2, scale: "v" },
      { label: theirs, stroke: KLIPPER_COLOUR, width: 2, dash: [6, 4], scale: "v" }],
  }, [r.frequency_hz, r.psd_normalized, r.recommended, r.klipper], el);
  const interval = recommendation.robust_over.frequency_ratio_interval;
  $("spectrum-note").textContent = "Right axis: the share of the vibration each shaper leaves at each frequency "
    + "(at its worst over damping ratios 0.075 to 0.15, as Klipper's graph). Robust over "
    + `${fixed(interval[0], 4)} to ${fixed(interval[1], 4)} × the measured frequencies `
    + `(${recommendation.robust_over.source}).`;
}

$("printer-form").addEventListener("submit", analyse);
$("record").addEventListener("change", () => { lastText = ""; });
$("copy-button").addEventListener("click", async () => {
  try {
    await navigator.clipboard.writeText($("firmware-text").textContent);
    $("status").textContent = "Copied.";
  } catch (error) {
    $("status").textContent = "Select the setting and copy it (the clipboard is not available here).";
  }
});
