// Tiny DOM helpers: h("div.card#id", {attrs}, children...) builds an element.

export function h(spec, attrs = {}, ...children) {
  const [, tag = "div", rest = ""] = spec.match(/^([a-z0-9]*)(.*)$/i);
  const el = document.createElement(tag || "div");
  for (const part of rest.match(/[.#][^.#]+/g) || []) {
    if (part[0] === ".") el.classList.add(part.slice(1));
    else el.id = part.slice(1);
  }
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith("on") && typeof value === "function") el.addEventListener(key.slice(2), value);
    else if (key === "dataset") Object.assign(el.dataset, value);
    else if (key in el && typeof value !== "string") el[key] = value;
    else el.setAttribute(key, value === true ? "" : String(value));
  }
  append(el, children);
  return el;
}

function append(el, children) {
  for (const child of children.flat(Infinity)) {
    if (child === null || child === undefined || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
}

export function clear(el, ...children) {
  el.replaceChildren();
  append(el, children);
  return el;
}

export function fmt(value, digits = 2) {
  if (value === null || value === undefined) return "–";
  if (typeof value === "number") return Number.isInteger(value) ? String(value) : value.toFixed(digits);
  return String(value);
}

let toastHost = null;
const MAX_TOASTS = 4;
/** A note in the corner; the same note again counts up instead of stacking (a fault that repeats). */
export function toast(message, kind = "info", ms = 4000) {
  toastHost ||= document.getElementById("toasts");
  let el = [...toastHost.children].find((t) => t.dataset.message === message);
  if (el) {
    el.dataset.count = String(Number(el.dataset.count || 1) + 1);
    el.querySelector(".count").textContent = `×${el.dataset.count}`;
    clearTimeout(el.timer);
    el.classList.remove("gone");
  } else {
    el = h(`div.toast.${kind}`, { dataset: { message } }, message, h("span.count"));
    toastHost.append(el);
    while (toastHost.children.length > MAX_TOASTS) toastHost.firstChild.remove();
  }
  el.timer = setTimeout(() => {
    el.classList.add("gone");
    setTimeout(() => el.classList.contains("gone") && el.remove(), 400);
  }, ms);
}

export function throttle(fn, ms) {
  let last = 0, timer = null, pending = null;
  return (...args) => {
    pending = args;
    const wait = last + ms - performance.now();
    if (wait <= 0) {
      last = performance.now();
      fn(...pending);
      pending = null;
    } else if (!timer) {
      timer = setTimeout(() => {
        timer = null;
        last = performance.now();
        if (pending) fn(...pending);
        pending = null;
      }, wait);
    }
  };
}
