// The programs page: a machine program (POST /v1/programs, NDJSON progress) drawn as its path in the plane, its
// axes against time and each stop's residual. No framework, no build step: uPlot draws the time plot, an SVG the path.
"use strict";

const $ = (id) => document.getElementById(id);
const COLOURS = ["#1f6fb4", "#c2410c", "#15803d", "#7c3aed", "#b45309", "#0e7490", "#be185d", "#4d7c0f"];
let timePlot = null;
let examples = {};

function fixed(value, digits) {
  return value === null || value === undefined || !Number.isFinite(value) ? "-" : value.toFixed(digits);
}

function sci(value) {
  return value === null || value === undefined || !Number.isFinite(value) ? "-" : value.toExponential(1);
}

function clearErrors() {
  document.querySelectorAll(".field-error, .form-error").forEach((el) => { el.textContent = ""; });
  $("program").removeAttribute("aria-invalid");
}

// A problem+json: every error names its field (axes[1].name, moves[3].target.x, ...), shown under the text box.
function showProblem(problem) {
  const errors = problem.errors && problem.errors.length ? problem.errors : [{ field: problem.field, rule: problem.detail }];
  $("err-body").textContent = errors.map((e) => `${e.field ? e.field + ": " : ""}${e.rule || problem.detail}`).join("\n");
  $("program").setAttribute("aria-invalid", "true");
}

async function loadExamples() {
  try {
    const spec = await (await fetch("/openapi.json")).json();
    examples = spec.paths["/v1/programs"].post.requestBody.content["application/json"].examples;
  } catch (error) {
    examples = {};
  }
  if (!$("program").value && examples.pick_and_place) fillExample("pick_and_place");
}

function fillExample(name) {
  if (examples[name]) $("program").value = JSON.stringify(examples[name].value, null, 2);
}

async function setExample(name) {
  await examplesLoaded; // a click before the examples arrive fills the box once they have
  fillExample(name);
}

async function design(event) {
  event.preventDefault();
  clearErrors();
  let body;
  try {
    body = JSON.parse($("program").value);
  } catch (error) {
    $("err-body").textContent = "body: not JSON (" + error.message + ")";
    $("program").setAttribute("aria-invalid", "true");
    return;
  }
  $("design-button").disabled = true;
  $("design-progress").hidden = false;
  $("status").textContent = "Designing…";
  try {
    const response = await fetch("/v1/programs?format=ndjson", {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body),
    });
    if (!response.ok) {
      showProblem(await response.json());
      $("status").textContent = `Not designed (${response.status}).`;
      return;
    }
    const answer = await readLines(response);
    if (answer) {
      show(answer);
      $("status").textContent = "";
    }
  } catch (error) {
    $("form-error").textContent = "The service did not answer: " + error;
    $("status").textContent = "";
  } finally {
    $("design-button").disabled = false;
    $("design-progress").hidden = true;
  }
}

// The NDJSON lines as they come: each `move` line is progress, the `program` line the answer.
async function readLines(response) {
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffered = "";
  let answer = null;
  for (;;) {
    const { value, done } = await reader.read();
    buffered += decoder.decode(value || new Uint8Array(), { stream: !done });
    let cut;
    while ((cut = buffered.indexOf("\n")) >= 0) {
      const line = JSON.parse(buffered.slice(0, cut));
      buffered = buffered.slice(cut + 1);
      if (line.line === "move") {
        $("status").textContent = `${line.done} of ${line.of} moves designed…`;
      } else if (line.line === "program") {
        answer = line;
      }
    }
    if (done) return answer;
  }
}

function cell(tr, text, header) {
  const el = document.createElement(header ? "th" : "td");
  if (header) el.scope = header;
  el.textContent = text;
  tr.appendChild(el);
}

function show(answer) {
  $("program-results").hidden = false;
  const names = Object.keys(answer.axes);
  $("cycle-summary").textContent = `Cycle time ${fixed(answer.cycle_time_s, 4)} s over ${answer.moves.length} moves `
    + `(${names.join(", ")}).`;
  const tbody = $("comparison-table").querySelector("tbody");
  tbody.replaceChildren();
  const ours = document.createElement("tr");
  cell(ours, "This program", "row");
  cell(ours, fixed(answer.cycle_time_s, 4));
  cell(ours, "1");
  cell(ours, sci(Math.max(...answer.moves.flatMap((m) => Object.values(m.axes).map((a) => a.stop_residual_fraction || 0)))));
  tbody.appendChild(ours);
  for (const row of answer.comparison) {
    const tr = document.createElement("tr");
    cell(tr, row.method, "row");
    cell(tr, row.cycle_time_s === null ? row.reason : fixed(row.cycle_time_s, 4));
    cell(tr, fixed(row.cycle_time_ratio, 3));
    cell(tr, sci(row.max_stop_residual_fraction));
    tbody.appendChild(tr);
  }
  drawPath(answer, names);
  drawTime(answer, names);
  stopsTable(answer, names);
  $("warnings").replaceChildren(...answer.warnings.map((w) => {
    const li = document.createElement("li");
    li.textContent = w;
    return li;
  }));
}

// The first two axes in their plane (an SVG: uPlot draws functions of one variable), the motor's path and the
// load's, and a dot at each stop.
function drawPath(answer, names) {
  const el = $("path-plot");
  el.replaceChildren();
  if (names.length < 2) {
    $("path-note").textContent = "One axis: no plane to draw.";
    return;
  }
  const [a, b] = names.map((n) => answer.axes[n]);
  const xs = [...a.profile.position, ...a.load.position];
  const ys = [...b.profile.position, ...b.load.position];
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const width = Math.max(320, Math.min(el.clientWidth || 700, 700));
  const span = Math.max(x1 - x0, y1 - y0) || 1;
  const pad = 0.06 * span;
  const scale = (width - 60) / (span + 2 * pad);
  const height = Math.round((y1 - y0 + 2 * pad) * scale + 40);
  const px = (x) => 40 + (x - x0 + pad) * scale;
  const py = (y) => height - 20 - (y - y0 + pad) * scale;
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("width", width);
  svg.setAttribute("height", height);
  svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
  const line = (x, y, colour, dash) => {
    const path = document.createElementNS(svg.namespaceURI, "polyline");
    path.setAttribute("points", x.map((v, i) => `${px(v).toFixed(1)},${py(y[i]).toFixed(1)}`).join(" "));
    path.setAttribute("fill", "none");
    path.setAttribute("stroke", colour);
    path.setAttribute("stroke-width", "1.5");
    if (dash) path.setAttribute("stroke-dasharray", dash);
    svg.appendChild(path);
  };
  line(a.profile.position, b.profile.position, COLOURS[0]);
  line(a.load.position, b.load.position, COLOURS[1], "4 3");
  const stop = (x, y, label) => {
    const dot = document.createElementNS(svg.namespaceURI, "circle");
    dot.setAttribute("cx", px(x));
    dot.setAttribute("cy", py(y));
    dot.setAttribute("r", 4);
    dot.setAttribute("fill", "#24292f");
    svg.appendChild(dot);
    const text = document.createElementNS(svg.namespaceURI, "text");
    text.setAttribute("x", px(x) + 6);
    text.setAttribute("y", py(y) - 6);
    text.setAttribute("font-size", "12");
    text.textContent = label;
    svg.appendChild(text);
  };
  const body = JSON.parse($("program").value);
  const labels = new Map();  // one dot a place, every stop there named ("start, 7")
  const name = (x, y, label) => {
    const key = `${x},${y}`;
    labels.set(key, labels.has(key) ? { x, y, text: labels.get(key).text + ", " + label } : { x, y, text: label });
  };
  name(body.start[names[0]], body.start[names[1]], "start");
  body.moves.forEach((m, k) => name(m.target[names[0]], m.target[names[1]], String(k)));
  for (const place of labels.values()) stop(place.x, place.y, place.text);
  el.appendChild(svg);
  $("path-note").textContent = `${names[0]} across, ${names[1]} up, equal scales: the motor (solid) and the load `
    + "(dashed), the stops numbered by move.";
}

function drawTime(answer, names) {
  const el = $("time-plot");
  if (timePlot) timePlot.destroy();
  const first = answer.axes[names[0]];
  const data = [first.profile.time_s];
  const series = [{ label: "t (s)" }];
  names.forEach((name, i) => {
    data.push(answer.axes[name].profile.position, answer.axes[name].load.position);
    series.push({ label: `${name} motor`, stroke: COLOURS[i % COLOURS.length], width: 2 },
      { label: `${name} load`, stroke: COLOURS[i % COLOURS.length], width: 1, dash: [5, 3] });
  });
  timePlot = new uPlot({
    width: Math.max(320, Math.min(el.clientWidth || 800, 1100)), height: 300,
    scales: { x: { time: false } },
    axes: [{ label: "time (s)" }, { label: "position (each axis's units)", size: 70 }],
    series,
  }, data, el);
}

function stopsTable(answer, names) {
  const head = $("stops-head");
  head.replaceChildren();
  for (const label of ["Move", "Coordination", "Start (s)", "Duration (s)", "Settling (s)",
    ...names.map((n) => `${n} residual`)]) {
    cell(head, label, "col");
  }
  const tbody = $("stops-table").querySelector("tbody");
  tbody.replaceChildren();
  for (const move of answer.moves) {
    const tr = document.createElement("tr");
    cell(tr, String(move.index), "row");
    cell(tr, move.coordination.replace("_", " ") + (move.varying ? " (mode varies)" : ""));
    cell(tr, fixed(move.start_s, 3));
    cell(tr, fixed(move.duration_s, 4));
    cell(tr, fixed(move.settling_time_s, 4));
    for (const name of names) {
      const axis = move.axes[name];
      cell(tr, axis.stop_residual_fraction === null ? "stays" : sci(axis.stop_residual_fraction));
    }
    tbody.appendChild(tr);
  }
}

$("program-form").addEventListener("submit", design);
const examplesLoaded = loadExamples();
$("example-line").addEventListener("click", () => setExample("straight_line"));
$("example-pick").addEventListener("click", () => setExample("pick_and_place"));
