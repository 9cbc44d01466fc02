// Calibrate: the procedure of `servoface calibrate` with buttons. The server runs it; each button
// answers the current prompt (capture, jog, go to, relax, next, abort) and the page shows the next one.

import { h, clear, fmt } from "./dom.js";
import { drawCurve } from "./curveplot.js";

let ctx, root, cal = null, visible = false, twinSeq = 0, pointsAsked = 3;
const STEPS = ["neutral", "lower", "upper", "point", "extra"];

export function mount(el, c) {
  ctx = c;
  root = h("div.calibrate");
  el.append(root);
  ctx.live.on("calibrate", (msg) => render(msg.state || msg));
  render({ active: false });
}

function reply(body) {
  return ctx.api
    .post("/api/calibrate/reply", body)
    .then(render)
    .catch(ctx.report);
}

function setupForm() {
  const roles = ctx.head.servos.map((s) =>
    h("label.role-pick", {}, h("input", { type: "checkbox", value: s.role, dataset: { role: s.role } }), ` ${s.role}`, h("span.muted", {}, ` #${s.id}`)),
  );
  const points = h("input.num#cal-points", { type: "number", min: "0", max: "20", value: "3" });
  const curve = h(
    "select#cal-curve",
    {},
    h("option", { value: "" }, "auto (linear joints, pchip anchors)"),
    ["linear", "piecewise_linear", "pchip"].map((k) => h("option", { value: k }, k)),
  );
  const out = h("input#cal-out", { type: "text", value: `calibration-${ctx.head.name.replace(/[^A-Za-z0-9_.-]/g, "_")}.json`, size: "32" });
  const start = () => {
    const picked = roles.map((l) => l.querySelector("input")).filter((i) => i.checked).map((i) => i.value);
    pointsAsked = Number(points.value) || 0;
    ctx.api
      .post("/api/calibrate/start", {
        roles: picked.length ? picked : null,
        points: Number(points.value) || 0,
        curve: curve.value || null,
        out: out.value.trim(),
      })
      .then(render)
      .catch(ctx.report);
  };
  return h(
    "div.card",
    {},
    h("div.card-head", {}, h("h3", {}, "Calibrate servos"), h("span.muted", {}, "the same procedure, checks and file as servoface calibrate")),
    h("p.muted", {}, "Pick the servos to measure (none picked: all). Each servo goes through neutral, lower and upper, then the intermediate points; torque is off so you can move it by hand, or jog it within the safe window."),
    h("div.role-grid", {}, roles),
    h("div.form-row", {}, h("label", {}, "intermediate points ", points), h("label", {}, "curve ", curve), h("label", {}, "save as ", out)),
    h("div.form-row", {}, h("button.btn.primary#cal-start", { onclick: start }, "Start calibration")),
  );
}

function promptCard(state) {
  const p = state.prompt;
  const step = h("input.num#cal-step", { type: "number", min: "1", max: "300", value: "10" });
  const gotoTick = h("input.num#cal-goto", { type: "number", min: "0", max: "4095", value: String(p.suggested_tick ?? p.present_tick) });
  const target = h("input.num#cal-target", { type: "number", step: "any", placeholder: p.target == null ? "enter" : fmt(p.target, 3), title: "leave empty to capture at the asked target" });
  const jog = (sign) => reply({ action: "jog", delta_tick: sign * (Number(step.value) || 1) });
  const spec = ctx.head.servos.find((x) => x.role === p.role);
  const skipped = new Set(spec ? [...(spec.lower === spec.neutral ? ["lower"] : []), ...(spec.upper === spec.neutral ? ["upper"] : [])] : []);
  if (!(pointsAsked > 0) && p.step !== "point") skipped.add("point");
  const done = new Set((state.captured || []).filter((c) => c.role === p.role).map((c) => c.step));
  const steps = STEPS.slice(0, 4).filter((s) => !skipped.has(s)).map((s) => h(`span.step${s === p.step ? ".current" : done.has(s) ? ".done" : ""}`, {}, done.has(s) && s !== p.step ? `✓ ${s}` : s));
  // Only what the user typed overrides the asked target (a rounded copy of it must not).
  const captureBody = () => (target.value.trim() !== "" ? { action: "capture", target: Number(target.value) } : { action: "capture", target: null });
  return h(
    "div.card.prompt",
    {},
    h("div.card-head", {}, h("h3", {}, `${p.role}`), h("span.muted", {}, `servo #${p.servo_id} · ${p.unit}`), h("span.grow"), h("div.steps", {}, steps)),
    h("p.prompt-text#cal-prompt", {}, p.text),
    h(
      "div.present",
      {},
      h("div", {}, h("span.muted", {}, "present"), h("b#cal-present", {}, fmt(p.present_tick))),
      h("div", {}, h("span.muted", {}, "target"), h("b", {}, p.target == null ? "you enter it" : `${fmt(p.target)} ${p.unit}`)),
      h("div", {}, h("span.muted", {}, "suggested"), h("b", {}, p.suggested_tick == null ? "–" : fmt(p.suggested_tick))),
    ),
    h(
      "div.form-row",
      {},
      h("button.btn#cal-jog-down", { onclick: () => jog(-1) }, "◀ jog"),
      step,
      h("button.btn#cal-jog-up", { onclick: () => jog(1) }, "jog ▶"),
      h("button.btn#cal-suggested", { disabled: p.suggested_tick == null, onclick: () => reply({ action: "goto_suggested" }) }, `Move to ${p.step}`),
      gotoTick,
      h("button.btn#cal-goto-btn", { onclick: () => reply({ action: "goto", tick: Number(gotoTick.value) }) }, "Go to tick"),
      h("button.btn.ghost#cal-relax", { onclick: () => reply({ action: "relax" }), title: "torque off: move the servo by hand" }, "Relax (by hand)"),
    ),
    h(
      "div.form-row",
      {},
      h("label", {}, `captured target (${p.unit}) `, target),
      h("button.btn.primary#cal-capture", { onclick: () => reply(captureBody()) }, "Capture"),
      h("button.btn#cal-next", { onclick: () => reply({ action: "finish" }), title: "skip this point (neutral, lower and upper are required)" }, "Next"),
      h("span.grow"),
      h("button.btn.danger-ghost#cal-abort", { onclick: () => reply({ action: "abort" }) }, "Abort"),
    ),
  );
}

function resultCard(state) {
  const r = state.result;
  return h(
    "div.card",
    {},
    h("div.card-head", {}, h("h3", {}, "Calibration saved"), h("span.muted#cal-saved", {}, r.saved_to)),
    h(
      "p#cal-applied",
      {},
      r.applied
        ? "In use now: the head drives with this calibration from the next frame on (its limits are written to the servos)."
        : "Saved only: the head still drives with the calibration it started with.",
    ),
    h(
      "table.servos",
      {},
      h("thead", {}, h("tr", {}, ["role", "curve", "min", "neutral", "max", "max residual"].map((t) => h("th", {}, t)))),
      h(
        "tbody",
        {},
        r.servos.map((s) => h("tr", {}, h("td.role", {}, s.role), h("td", {}, s.kind), h("td.num", {}, s.min_tick), h("td.num", {}, s.neutral_tick), h("td.num", {}, s.max_tick), h("td.num", {}, fmt(s.max_residual_tick, 1)))),
      ),
    ),
    r.warnings.length ? h("ul.reasons", {}, r.warnings.map((w) => h("li", {}, w))) : null,
    h("div.plots", {}, r.plots.map((role) => h("img.plot", { src: `/api/calibrate/plot/${encodeURIComponent(role)}.png`, alt: `${role} curve` }))),
    h("div.form-row", {}, h("button.btn", { onclick: () => ((shownKey = ""), render({ active: false })) }, "Calibrate again")),
  );
}

function helpCard() {
  return h(
    "div.card",
    {},
    h("h3", {}, "How it goes"),
    h(
      "ol.help",
      {},
      h("li", {}, "Torque goes off on the servo: move it by hand, or jog it (torque comes on, the goal pinned first)."),
      h("li", {}, "Bring it to the asked target (", h("b", {}, "Move to"), " goes where the current calibration puts it) and press ", h("b", {}, "Capture"), "."),
      h("li", {}, "After neutral, lower and upper the servo's own position limits are set to the captured range; the points between follow."),
      h("li", {}, "The points are fitted and checked (monotone, coverage, residuals); a bad fit asks again. The file is written atomically at the end."),
    ),
    h("p.muted", {}, "Jogs and go-tos outside the safe window, or more than 300 ticks at once, are refused and say why. The E-stop aborts the session; nothing is saved."),
  );
}

let shownKey = "", curveArgs = null;

function render(state) {
  // The server pushes the present tick every 0.25 s: then only it changes (inputs keep what is typed).
  const p = state.prompt;
  const key = JSON.stringify([state.active, state.done, state.error, p && [p.role, p.step, p.target, p.suggested_tick], (state.captured || []).length, (state.messages || []).length]);
  if (key === shownKey && p && curveArgs) {
    cal = state;
    const present = root.querySelector("#cal-present");
    if (present) present.textContent = fmt(p.present_tick);
    const canvas = root.querySelector("#cal-curve-canvas");
    if (canvas) drawCurve(canvas, { ...curveArgs, present: p.present_tick });
    return;
  }
  shownKey = key;
  cal = state;
  const active = state.active && state.prompt;
  const left = h("div.col");
  if (state.error) left.append(h("div.banner.danger", {}, state.error));
  if (active) left.append(promptCard(state));
  else if (state.done && state.result) left.append(resultCard(state));
  else left.append(setupForm());
  const right = h("div.col");
  const messages = (state.messages || []).slice(-8);
  if (messages.length) right.append(h("div.card", {}, h("h3", {}, "Messages"), h("ul.log", {}, messages.map((m) => h("li", {}, m)))));
  if (!active) right.append(helpCard());
  if (active) {
    const p = state.prompt;
    const canvas = h("canvas.curve#cal-curve-canvas");
    const img = h("img.twin-img#cal-twin", { alt: "the twin posed at the prompted target", src: `/api/calibrate/twin.png?v=${++twinSeq}` });
    const servo = ctx.head.servos.find((s) => s.role === p.role);
    right.prepend(h("div.card", {}, h("div.card-head", {}, h("h3", {}, "Twin at the target"), h("span.muted", {}, p.target == null ? "" : `${p.role} at ${fmt(p.target)} ${p.unit}`)), h("figure.twin-fig", {}, img)));
    left.insertBefore(h("div.card", {}, h("div.card-head", {}, h("h3", {}, "Curve"), h("span.muted", {}, `${p.role}: captured points, target → tick; dashed: where it is now`)), canvas), left.children[state.error ? 2 : 1] || null);
    const captured = (state.captured || []).filter((c) => c.role === p.role);
    curveArgs = { unit: p.unit, points: captured, target: p.target, range: servo ? [servo.lower, servo.upper] : null };
    requestAnimationFrame(() => drawCurve(canvas, { ...curveArgs, present: p.present_tick }));
  }
  clear(root, h("div.cal-grid", {}, left, right));
  root.dataset.step = active ? state.prompt.step : state.done ? "done" : "idle";
}

export function show() {
  visible = true;
  ctx.api.get("/api/calibrate").then((s) => (s.active || s.done ? render(s) : null)).catch(() => {});
}

export function hide() {
  visible = false;
}
