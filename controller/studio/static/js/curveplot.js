// The calibration curve on a canvas: captured points (target -> tick), the line through them, the
// servo's present tick and the prompted target.

export function drawCurve(canvas, { unit = "", points = [], present = null, target = null, range = null } = {}) {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth || 420, hgt = canvas.clientHeight || 260;
  canvas.width = w * dpr;
  canvas.height = hgt * dpr;
  const g = canvas.getContext("2d");
  g.scale(dpr, dpr);
  g.clearRect(0, 0, w, hgt);
  const css = getComputedStyle(document.body);
  const ink = css.getPropertyValue("--ink").trim() || "#ddd";
  const muted = css.getPropertyValue("--muted").trim() || "#888";
  const accent = css.getPropertyValue("--accent").trim() || "#4c8dff";
  const grid = css.getPropertyValue("--line").trim() || "#333";
  const pad = { l: 54, r: 14, t: 14, b: 34 };

  const xs = points.map((p) => p.target).filter((v) => v != null);
  const ys = points.map((p) => p.tick);
  if (range) xs.push(range[0], range[1]);
  if (target != null) xs.push(target);
  if (present != null) ys.push(present);
  if (!xs.length) xs.push(-1, 1);
  if (!ys.length) ys.push(2000, 2100);
  let [x0, x1] = [Math.min(...xs), Math.max(...xs)];
  let [y0, y1] = [Math.min(...ys), Math.max(...ys)];
  if (x1 - x0 < 1e-6) [x0, x1] = [x0 - 1, x1 + 1];
  if (y1 - y0 < 20) [y0, y1] = [y0 - 20, y1 + 20];
  const mx = (x1 - x0) * 0.06, my = (y1 - y0) * 0.08;
  x0 -= mx; x1 += mx; y0 -= my; y1 += my;
  const X = (v) => pad.l + ((v - x0) / (x1 - x0)) * (w - pad.l - pad.r);
  const Y = (v) => hgt - pad.b - ((v - y0) / (y1 - y0)) * (hgt - pad.t - pad.b);

  g.font = "11px system-ui, sans-serif";
  g.strokeStyle = grid;
  g.fillStyle = muted;
  g.lineWidth = 1;
  for (let i = 0; i <= 4; i++) {
    const xv = x0 + ((x1 - x0) * i) / 4, yv = y0 + ((y1 - y0) * i) / 4;
    g.beginPath(); g.moveTo(X(xv), pad.t); g.lineTo(X(xv), hgt - pad.b); g.stroke();
    g.beginPath(); g.moveTo(pad.l, Y(yv)); g.lineTo(w - pad.r, Y(yv)); g.stroke();
    g.textAlign = "center"; g.fillText(xv.toFixed(1), X(xv), hgt - pad.b + 14);
    g.textAlign = "right"; g.fillText(String(Math.round(yv)), pad.l - 6, Y(yv) + 4);
  }
  g.textAlign = "center";
  g.fillText(`target (${unit})`, (pad.l + w - pad.r) / 2, hgt - 6);
  g.save(); g.translate(12, (pad.t + hgt - pad.b) / 2); g.rotate(-Math.PI / 2); g.fillText("goal tick", 0, 0); g.restore();

  if (present != null) {
    g.strokeStyle = muted; g.setLineDash([4, 4]);
    g.beginPath(); g.moveTo(pad.l, Y(present)); g.lineTo(w - pad.r, Y(present)); g.stroke();
    g.setLineDash([]); g.textAlign = "left"; g.fillStyle = muted;
    g.fillText(`present ${present}`, pad.l + 4, Y(present) - 4);
  }
  if (target != null) {
    g.strokeStyle = accent; g.setLineDash([2, 4]);
    g.beginPath(); g.moveTo(X(target), pad.t); g.lineTo(X(target), hgt - pad.b); g.stroke();
    g.setLineDash([]);
  }
  const sorted = points.filter((p) => p.target != null).sort((a, b) => a.target - b.target);
  if (sorted.length > 1) {
    g.strokeStyle = accent; g.lineWidth = 2;
    g.beginPath();
    sorted.forEach((p, i) => (i ? g.lineTo(X(p.target), Y(p.tick)) : g.moveTo(X(p.target), Y(p.tick))));
    g.stroke();
  }
  for (const p of sorted) {
    g.fillStyle = ink; g.beginPath(); g.arc(X(p.target), Y(p.tick), 4.5, 0, Math.PI * 2); g.fill();
    g.fillStyle = accent; g.beginPath(); g.arc(X(p.target), Y(p.tick), 3, 0, Math.PI * 2); g.fill();
  }
}
