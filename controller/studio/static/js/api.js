// The studio's HTTP + WebSocket client (controller/studio/API.md). The token comes from the page's URL
// (?token=) and goes on every request; the server also set it as a cookie for <img src> loads.

const params = new URLSearchParams(location.search);
export const token = params.get("token") || sessionStorage.getItem("servoface_token") || "";
if (token) sessionStorage.setItem("servoface_token", token);

export class ApiError extends Error {
  constructor(status, body) {
    const err = (body && body.error) || {};
    super(err.message || `HTTP ${status}`);
    this.status = status;
    this.code = err.code || "";
    this.field = err.field || "";
  }
  describe() {
    // (a message that already starts with its field, as pydantic's do, is not prefixed twice)
    return this.field && !this.message.startsWith(`${this.field}:`) ? `${this.field}: ${this.message}` : this.message;
  }
}

async function request(method, path, body) {
  const init = { method, headers: { "X-Servoface-Token": token } };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const res = await fetch(path, init);
  const type = res.headers.get("Content-Type") || "";
  if (!res.ok) throw new ApiError(res.status, type.includes("json") ? await res.json() : null);
  if (type.includes("json")) return res.json();
  return res.blob();
}

export const api = {
  get: (path) => request("GET", path),
  post: (path, body = {}) => request("POST", path, body),
  put: (path, body = {}) => request("PUT", path, body),
};

/** One WebSocket to the head service with reconnects; `on(type, fn)` for server messages. */
export class Live {
  constructor() {
    this.handlers = new Map();
    this.ws = null;
    this.nextId = 1;
    this.waiting = new Map();
    this.subscription = { twin: false, target: false, telemetry: true, frames: true }; // Live turns the twin on
    this.retryMs = 500;
    this.beat = null;
  }

  /** The app-level heartbeat (API.md "Heartbeat"): every 0.25 s while the socket is open, so a silently
   * dead network eases the head to neutral within a second. Timed by a Worker where there is one: its
   * timers are not throttled when the tab is in the background (a page's are, to 1 Hz). */
  startHeartbeat() {
    if (this.beat) return;
    const tick = () => this.send({ type: "heartbeat" });
    try {
      const worker = new Worker(new URL("./heartbeat_worker.js", import.meta.url));
      worker.onmessage = tick;
      worker.postMessage({ interval_ms: 250 });
      this.beat = { stop: () => worker.terminate() };
    } catch (err) {
      const timer = setInterval(tick, 250);
      this.beat = { stop: () => clearInterval(timer) };
    }
  }

  on(type, fn) {
    if (!this.handlers.has(type)) this.handlers.set(type, new Set());
    this.handlers.get(type).add(fn);
    return () => this.handlers.get(type).delete(fn);
  }

  emit(type, msg) {
    for (const fn of this.handlers.get(type) || []) {
      try {
        fn(msg);
      } catch (err) {
        console.error(`studio: handler for ${type} failed`, err);
      }
    }
  }

  connect() {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${proto}://${location.host}/api/ws?token=${encodeURIComponent(token)}`);
    ws.binaryType = "arraybuffer";
    this.ws = ws;
    ws.onopen = () => {
      this.retryMs = 500;
      this.emit("open", {});
      this.send({ type: "subscribe", ...this.subscription });
      this.send({ type: "heartbeat" });
      this.startHeartbeat();
    };
    ws.onclose = (ev) => {
      this.emit("close", { code: ev.code, reason: ev.reason });
      for (const { reject } of this.waiting.values()) reject(new Error("connection closed"));
      this.waiting.clear();
      setTimeout(() => this.connect(), this.retryMs);
      this.retryMs = Math.min(this.retryMs * 2, 5000);
    };
    ws.onmessage = (ev) => {
      if (typeof ev.data !== "string") {
        const bytes = new Uint8Array(ev.data);
        const which = bytes[0] === 0x54 ? "target" : "achievable";
        const seq = new DataView(ev.data).getUint32(1, false);
        this.emit("twin-image", { which, seq, blob: new Blob([bytes.subarray(5)], { type: "image/png" }) });
        return;
      }
      const msg = JSON.parse(ev.data);
      if ((msg.type === "reply" || msg.type === "error") && msg.id != null && this.waiting.has(msg.id)) {
        const { resolve, reject } = this.waiting.get(msg.id);
        this.waiting.delete(msg.id);
        if (msg.type === "reply") resolve(msg.result);
        else reject(new ApiError(msg.error?.status || 400, msg));
      }
      this.emit(msg.type, msg);
    };
  }

  get open() {
    return this.ws && this.ws.readyState === WebSocket.OPEN;
  }

  send(msg) {
    if (!this.open) return false;
    this.ws.send(JSON.stringify(msg));
    return true;
  }

  /** Send and wait for the server's reply (rejects with an ApiError on an `error`). */
  call(msg) {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      if (!this.send({ ...msg, id })) return reject(new Error("not connected"));
      this.waiting.set(id, { resolve, reject });
    });
  }

  subscribe(changes) {
    Object.assign(this.subscription, changes);
    this.send({ type: "subscribe", ...this.subscription });
  }
}

export const live = new Live();
