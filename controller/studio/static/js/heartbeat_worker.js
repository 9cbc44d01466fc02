// The heartbeat's clock (see api.js startHeartbeat): a dedicated worker's timers keep their rate when the
// tab is in the background, so the page keeps saying "still here" to the head service.
let timer = null;
self.onmessage = (ev) => {
  if (timer !== null) clearInterval(timer);
  const ms = Math.max(50, Number(ev.data?.interval_ms) || 250);
  timer = setInterval(() => self.postMessage("beat"), ms);
};
