// The studio's shell: connection, the always-visible E-stop and hold, the banner, and the four pages.

import { api, live } from "./api.js";
import { clear, h, toast } from "./dom.js";
import * as livePage from "./live.js";
import * as servosPage from "./servos.js";
import * as calibratePage from "./calibrate.js";
import * as authorPage from "./author.js";

const PAGES = { live: livePage, servos: servosPage, calibrate: calibratePage, author: authorPage };
const ctx = { head: null, state: null, live, api, listeners: new Set() };
window.studio = ctx; // for the browser tests and the curious

ctx.onState = (fn) => {
  ctx.listeners.add(fn);
  if (ctx.state) fn(ctx.state);
};
ctx.report = (err) => toast(err.describe ? err.describe() : String(err.message || err), "error", 6000);

function setState(state) {
  ctx.state = state;
  for (const fn of ctx.listeners) fn(state);
}

function renderChrome(state) {
  const torque = document.getElementById("torque-pill");
  torque.textContent = state.torque_on ? "torque on" : "torque off";
  torque.className = `pill ${state.torque_on ? "ok" : "warn"}`;
  const hold = document.getElementById("hold");
  if (document.activeElement !== hold) hold.checked = !!state.hold;
  document.body.classList.toggle("latched", !!state.estop_latched);
  const banner = document.getElementById("banner");
  if (state.estop_latched) {
    banner.hidden = false;
    banner.className = "banner danger";
    clear(
      banner,
      h("b", {}, "E-stop latched."),
      " Goals stopped and torque is off on every servo. ",
      h("button.btn", { onclick: () => api.post("/api/estop/clear").catch(ctx.report) }, "Clear e-stop"),
    );
  } else if (!state.torque_on && !state.manual && !state.calibrating) {
    banner.hidden = false;
    banner.className = "banner warn";
    clear(
      banner,
      "Torque is off: the head will not move. ",
      h("button.btn", { onclick: () => api.post("/api/torque", { on: true }).catch(ctx.report) }, "Torque on"),
    );
  } else if (state.error) {
    banner.hidden = false;
    banner.className = "banner danger";
    clear(banner, h("b", {}, "Head service stopped: "), state.error);
  } else if (state.manual || state.calibrating) {
    banner.hidden = false;
    banner.className = "banner info";
    clear(banner, state.calibrating ? "A calibration holds the bus." : "Manual mode: the loop is paused, jog servos on the Servos page.");
  } else {
    banner.hidden = true;
  }
}

function estop() {
  // Both paths: the WebSocket is fastest, HTTP works when the socket is down.
  live.send({ type: "estop", reason: "studio button" });
  api.post("/api/estop", { reason: "studio button" }).catch(ctx.report);
  document.body.classList.add("latched");
}

function route() {
  const name = (location.hash || "#live").slice(1);
  const page = PAGES[name] ? name : "live";
  for (const [key, mod] of Object.entries(PAGES)) {
    const el = document.getElementById(`page-${key}`);
    const active = key === page;
    if (active && el.hidden) {
      el.hidden = false;
      mod.show?.();
    } else if (!active && !el.hidden) {
      el.hidden = true;
      mod.hide?.();
    }
  }
  for (const a of document.querySelectorAll("#tabs a")) a.classList.toggle("active", a.dataset.page === page);
}

async function boot() {
  document.getElementById("estop").addEventListener("click", estop);
  window.addEventListener("keydown", (ev) => {
    if (ev.key === "Escape") estop();
  });
  document.getElementById("hold").addEventListener("change", (ev) => {
    api.post("/api/hold", { hold: ev.target.checked }).catch(ctx.report);
  });
  const conn = document.getElementById("conn");
  live.on("open", () => {
    conn.textContent = "connected";
    conn.className = "pill ok";
  });
  live.on("close", () => {
    conn.textContent = "reconnecting…";
    conn.className = "pill warn";
  });
  live.on("state", (msg) => setState(msg.state || msg));
  live.on("hello", (msg) => msg.state && setState(msg.state));
  live.on("fault", (msg) => {
    if (msg.kind === "estop") return; // the latched banner says it (one press reaches the server twice: socket and HTTP)
    toast(`${msg.kind}${msg.servo_id != null ? ` (servo ${msg.servo_id})` : ""}: ${msg.detail || ""}`, "warn");
  });
  live.on("error", (msg) => msg.id == null && toast(msg.error?.message || "refused", "error"));
  ctx.onState(renderChrome);
  try {
    ctx.head = await api.get("/api/head");
  } catch (err) {
    document.getElementById("head-name").textContent = "no head";
    toast(`Cannot reach the studio server: ${err.message}. Open the URL servoface studio printed (with its token).`, "error", 60000);
    return;
  }
  const kind = ctx.head.face_type === "dog" ? "dog · DFACS" : "human · FACS";
  document.getElementById("head-name").textContent = `${ctx.head.name === ctx.head.face_type ? "built-in" : ctx.head.name} ${kind} head · ${ctx.head.servos.length} servos · ${ctx.head.rate_hz} Hz`;
  for (const [key, mod] of Object.entries(PAGES)) mod.mount(document.getElementById(`page-${key}`), ctx);
  window.addEventListener("hashchange", route);
  route();
  live.connect();
  api.get("/api/state").then(setState).catch(() => {});
  document.body.dataset.ready = "1";
}

boot();
