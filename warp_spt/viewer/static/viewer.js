// warp_spt's live viewer: one ES module for both hosts.
//
// In Jupyter, anywidget calls render({model, el}) with a widget model; the browser page
// (index.html) calls it with a small adapter that gives a WebSocket the same interface:
// model.send(message) to the host, model.on("msg:custom", (message, buffers) => ...) from it.
// The host (warp_spt.viewer.session.Session) owns every piece of state; this module sends
// intents (drags, keys, control changes) and shows what comes back (frames, state, notices).

const STYLE = `
.wspt { display: flex; flex-wrap: wrap; gap: 10px; align-items: flex-start; outline: none;
  font: 12px/1.35 system-ui, sans-serif; color: #ddd; background: #1e1e1e; padding: 8px; border-radius: 4px; }
.wspt-view { position: relative; flex: 0 0 auto; max-width: 100%; }
.wspt canvas { display: block; max-width: 100%; background: #111; cursor: grab; touch-action: none; }
.wspt canvas.dragging { cursor: grabbing; }
.wspt-status { margin-top: 4px; font-variant-numeric: tabular-nums; white-space: pre-wrap; }
.wspt-camera { color: #999; font-size: 11px; font-variant-numeric: tabular-nums; }
.wspt-error { display: none; background: #5a1d1d; border: 1px solid #c44; color: #fdd; padding: 6px 8px;
  margin-bottom: 6px; white-space: pre-wrap; max-width: 640px; }
.wspt-notice { position: absolute; left: 8px; top: 8px; right: 8px; background: rgba(0,0,0,.75); padding: 4px 6px;
  display: none; pointer-events: none; white-space: pre-line; }
.wspt-panel { flex: 0 1 290px; min-width: 240px; }
.wspt details { border-top: 1px solid #333; padding: 3px 0; }
.wspt summary { cursor: pointer; font-weight: 600; padding: 2px 0; }
.wspt label { display: flex; align-items: center; gap: 6px; margin: 3px 0; }
.wspt label > span:first-child { flex: 0 0 84px; color: #aaa; }
.wspt input, .wspt select, .wspt button, .wspt textarea { font: inherit; color: #eee; background: #2b2b2b;
  border: 1px solid #555; border-radius: 3px; padding: 1px 4px; }
.wspt input[type=number] { width: 64px; }
.wspt input[type=range] { flex: 1; min-width: 60px; }
.wspt input[type=color] { padding: 0; width: 32px; height: 20px; }
.wspt button { cursor: pointer; margin: 2px 2px 2px 0; }
.wspt button:hover { background: #3a3a3a; }
.wspt textarea { width: 100%; box-sizing: border-box; height: 7.5em; font-family: ui-monospace, monospace; font-size: 11px; }
.wspt-help { color: #888; font-size: 11px; margin-top: 4px; }
.wspt-notes { color: #db8; font-size: 11px; }
`;

const ORBIT_KEY_STEP = 5 / 180;     // a key press swings the camera by 5 degrees
const PAN_KEY_STEP = 0.05;          // ... or slides it by 5% of the view
const NOTICE_MS = 5000;

export default { render };

export function render({ model, el }) {
  const ui = build(el);
  const view = { settings: null, params: [], lastSeq: 0, drawn: 0, fpsTimes: [], group: null };
  const send = (message) => model.send(message);
  const onMessage = (message, buffers) => receive(ui, view, send, message, buffers || []);
  model.on("msg:custom", onMessage);
  wirePointer(ui, send);
  wireKeys(ui, view, send);
  wireControls(ui, view, send);
  send({ type: "hello" });
  return () => model.off("msg:custom", onMessage);
}

// ---------------------------------------------------------------- DOM

function h(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
}

function field(label, input) {
  return h("label", {}, h("span", {}, label), input);
}

// three number fields for a vector or an RGB colour; get() reads them, set(v) shows v
function vec3(cls, step, min) {
  const inputs = [0, 1, 2].map((i) => h("input", { type: "number", step, class: `${cls}-${i}`,
                                                 style: "width:52px", ...(min === undefined ? {} : { min }) }));
  return { el: h("span", { class: cls }, ...inputs), inputs,
           get: () => inputs.map((x) => Number(x.value)),
           set: (v) => inputs.forEach((x, i) => setValue(x, +Number(v[i]).toPrecision(6))) };
}

function select(options) {
  const s = h("select");
  setOptions(s, options);
  return s;
}

function setOptions(sel, options) {
  const current = Array.from(sel.options).map((o) => o.value).join("\n");
  if (current === options.join("\n")) return;
  sel.replaceChildren(...options.map((o) => h("option", { value: o }, o)));
}

function build(el) {
  const style = h("style", {}, STYLE);
  const canvas = h("canvas", { width: "384", height: "288", "aria-label": "rendered view" });
  const ui = {
    root: h("div", { class: "wspt", tabindex: "0", "data-lm-suppress-shortcuts": "true",
                     "data-p-suppress-shortcuts": "true" }),
    canvas, ctx: canvas.getContext("2d"),
    status: h("div", { class: "wspt-status" }, "connecting..."),
    camera: h("div", { class: "wspt-camera" }),
    error: h("div", { class: "wspt-error" }),
    errorText: h("span"),
    reload: h("button", { type: "button" }, "Reload scene"),
    notice: h("div", { class: "wspt-notice" }),
    width: h("input", { type: "number", min: "8", max: "4096", step: "8" }),
    height: h("input", { type: "number", min: "8", max: "4096", step: "8" }),
    fov: h("input", { type: "range", min: "1", max: "170", step: "0.5" }),
    fovValue: h("input", { type: "number", min: "1", max: "170", step: "0.5", style: "width:52px" }),
    aperture: h("input", { type: "number", min: "0", step: "0.01" }),
    up: select(["z", "y", "x", "-z", "-y", "-x"]),
    frame: h("button", { type: "button", title: "F" }, "Frame"),
    reset: h("button", { type: "button", title: "R" }, "Reset"),
    integrator: select([]), sampler: select([]),
    depth: h("input", { type: "number", min: "1", max: "4096" }),
    sky: select([]), skyColor: h("input", { type: "color" }),
    envPath: h("input", { type: "text", size: "14", placeholder: "sky.hdr", class: "wspt-env-path" }),
    envRotate: h("input", { type: "number", step: "5", style: "width:52px", title: "rotate (degrees)" }),
    envStrength: h("input", { type: "number", min: "0", step: "0.1", style: "width:52px", title: "strength" }),
    envBackdrop: h("input", { type: "checkbox", class: "wspt-env-backdrop", title: "camera rays see a colour" }),
    envBackground: h("input", { type: "color", class: "wspt-env-background" }),
    // the page's lights and fog (viewer/lighting.py): vectors as three number fields
    sun: h("input", { type: "checkbox", class: "wspt-sun" }),
    sunDirection: vec3("wspt-sun-direction", "0.1"), sunColor: vec3("wspt-sun-color", "0.1", "0"),
    sunRadius: h("input", { type: "number", min: "0", max: "45", step: "0.1", class: "wspt-sun-radius" }),
    lamp: select(["off", "point", "spot"]),
    lampPosition: vec3("wspt-lamp-position", "0.1"), lampIntensity: vec3("wspt-lamp-intensity", "1", "0"),
    lampDirection: vec3("wspt-lamp-direction", "0.1"),
    lampAngle: h("input", { type: "number", min: "0.5", max: "90", step: "1", class: "wspt-lamp-angle" }),
    fog: h("input", { type: "checkbox", class: "wspt-fog" }),
    fogSigmaA: vec3("wspt-fog-sigma-a", "0.001", "0"), fogSigmaS: vec3("wspt-fog-sigma-s", "0.001", "0"),
    fogG: h("input", { type: "number", min: "-0.99", max: "0.99", step: "0.05", class: "wspt-fog-g" }),
    maxSpp: h("input", { type: "number", min: "1", step: "1", class: "wspt-max-spp" }),
    exposure: h("input", { type: "range", min: "-6", max: "6", step: "0.1" }),
    exposureValue: h("span"),
    tonemap: select(["filmic", "srgb", "seed"]),
    errorMap: h("input", { type: "checkbox" }),
    group: select([]), params: h("div"),
    saves: h("div"),
    cmdWidth: h("input", { type: "number", min: "1", max: "65536", class: "wspt-cmd-width" }),
    cmdHeight: h("input", { type: "number", min: "1", max: "65536", class: "wspt-cmd-height" }),
    cmdSpp: h("input", { type: "number", min: "1", value: "256", class: "wspt-cmd-spp" }),
    cmdOut: h("input", { type: "text", value: "view.png", size: "12", class: "wspt-cmd-out" }),
    copy: h("button", { type: "button", class: "wspt-copy" }, "Copy command line"),
    command: h("textarea", { readonly: "", class: "wspt-command", spellcheck: "false" }),
    notes: h("div", { class: "wspt-notes" }),
  };
  ui.error.append(ui.errorText, h("div", {}, ui.reload));
  const panel = h("div", { class: "wspt-panel" },
    h("details", { open: "" }, h("summary", {}, "View"),
      field("size", h("span", {}, ui.width, " x ", ui.height)),
      field("fov", h("span", { style: "display:flex;flex:1;gap:4px" }, ui.fov, ui.fovValue)),
      field("aperture", ui.aperture), field("up axis", ui.up), h("div", {}, ui.frame, ui.reset)),
    h("details", { open: "" }, h("summary", {}, "Render"),
      field("integrator", ui.integrator), field("sampler", ui.sampler), field("max depth", ui.depth),
      field("sky", h("span", {}, ui.sky, " ", ui.skyColor)),
      field("environment", h("span", {}, ui.envPath, " ", ui.envRotate, " ", ui.envStrength)),
      field("backdrop", h("span", {}, ui.envBackdrop, " ", ui.envBackground)),
      field("stop at spp", ui.maxSpp)),
    h("details", {}, h("summary", {}, "Lights and fog"),
      field("sun", ui.sun), field("towards", ui.sunDirection.el), field("irradiance", ui.sunColor.el),
      field("radius (deg)", ui.sunRadius),
      field("lamp", ui.lamp), field("position", ui.lampPosition.el), field("intensity", ui.lampIntensity.el),
      field("spot aims", ui.lampDirection.el), field("spot cone", ui.lampAngle),
      field("fog", ui.fog), field("sigma_a", ui.fogSigmaA.el), field("sigma_s", ui.fogSigmaS.el),
      field("g", ui.fogG)),
    h("details", { open: "" }, h("summary", {}, "Display"),
      field("exposure", h("span", { style: "display:flex;flex:1;gap:4px" }, ui.exposure, ui.exposureValue)),
      field("tone map", ui.tonemap), field("error map", ui.errorMap)),
    h("details", {}, h("summary", {}, "Materials"), field("material", ui.group), ui.params),
    h("details", { open: "" }, h("summary", {}, "Output"),
      field("save image", ui.saves),
      field("size", h("span", {}, ui.cmdWidth, " x ", ui.cmdHeight)),
      field("spp", ui.cmdSpp), field("output", ui.cmdOut), ui.copy, ui.command, ui.notes),
    h("div", { class: "wspt-help" },
      "drag: orbit \u00b7 right/shift-drag: pan \u00b7 wheel: dolly \u00b7 ctrl-wheel: fov \u00b7 " +
      "double-click: orbit target and focus \u00b7 keys: arrows orbit, WASD pan, +/- dolly, [ ] fov, " +
      "F frame, R reset, E error map, U up axis"));
  const viewBox = h("div", { class: "wspt-view" }, ui.error, canvas, ui.notice, ui.status, ui.camera);
  ui.root.append(style, viewBox, panel);
  el.append(ui.root);
  return ui;
}

// ---------------------------------------------------------------- messages from the host

function receive(ui, view, send, message, buffers) {
  switch (message.type) {
    case "frame": return showFrame(ui, view, message, buffers[0]);
    case "state": return showState(ui, view, send, message);
    case "notice": return notice(ui, message.text, message.level);
    case "status": ui.status.textContent = message.text; return;
    case "command": return showCommand(ui, message);
    case "file": return download(message, buffers[0]);
  }
}

async function showFrame(ui, view, message, buffer) {
  const seq = ++view.lastSeq;
  const bitmap = await createImageBitmap(new Blob([buffer], { type: "image/jpeg" }));
  if (seq !== view.lastSeq) { bitmap.close(); return; }     // a newer frame is on its way: skip this one
  const [w, h] = message.view;
  if (ui.canvas.width !== w || ui.canvas.height !== h) { ui.canvas.width = w; ui.canvas.height = h; }
  ui.ctx.imageSmoothingEnabled = true;
  ui.ctx.imageSmoothingQuality = "high";       // previews are an eighth of the size: interpolate them
  ui.ctx.drawImage(bitmap, 0, 0, w, h);
  bitmap.close();
  view.drawn += 1;
  const now = performance.now();
  if (message.mode === "preview") view.fpsTimes = view.fpsTimes.filter((t) => now - t < 1000).concat([now]);
  const fps = view.fpsTimes.length > 1 ? (view.fpsTimes.length - 1) * 1000 / (now - view.fpsTimes[0]) : 0;
  ui.status.textContent = statusLine(message, fps);
  ui.camera.textContent = cameraLine(message.camera);
  Object.assign(ui.root.dataset, { frames: String(view.drawn), mode: message.mode, spp: String(message.spp),
                                   version: String(message.version), size: message.size.join("x"),
                                   fps: fps.toFixed(1), error: message.error == null ? "" : String(message.error) });
}

function statusLine(m, fps) {
  const rate = m.rate >= 1e6 ? `${(m.rate / 1e6).toFixed(2)} M` : `${(m.rate / 1e3).toFixed(0)} k`;
  if (m.mode === "preview") {
    return `moving \u00b7 preview ${m.size[0]}x${m.size[1]}, ${m.spp} spp \u00b7 ${fps.toFixed(1)} fps \u00b7 ${rate} samples/s`;
  }
  const err = m.error == null ? "n/a" : `${(100 * m.error).toFixed(2)}%`;
  return `${m.spp} spp \u00b7 estimated relative error ${err} \u00b7 ${rate} samples/s` +
         (m.error_map ? `\nerror map (relative standard error, log scale): black ${pct(m.error_range[0])} ` +
                        `\u2026 red \u2026 yellow \u2026 white ${pct(m.error_range[1])}` : "");
}

function pct(x) {
  return `${+(100 * x).toPrecision(3)}%`;
}

function cameraLine(c) {
  if (!c) return "";
  const v = (a) => a.map((x) => x.toPrecision(4)).join(" ");
  return `camera ${v(c.position)} \u2192 ${v(c.direction)} \u00b7 fov ${c.fov.toFixed(1)} \u00b7 ` +
         `focus ${c.focus.toPrecision(4)} \u00b7 aperture ${c.aperture}`;
}

function setValue(input, value) {
  if (document.activeElement === input) return;      // never fight the user's typing
  if (input.type === "checkbox") input.checked = !!value;
  else input.value = value;
}

function showState(ui, view, send, st) {
  const s = st.settings;
  view.settings = s;
  ui.error.style.display = st.error ? "block" : "none";
  ui.errorText.textContent = st.error || "";
  ui.reload.style.display = st.can_reload ? "" : "none";
  ui.root.dataset.viewers = String(st.viewers);        // tabs showing this one session (the host says so)
  if (st.loading) ui.status.textContent = "loading the scene...";
  setOptions(ui.integrator, st.integrators);
  setOptions(ui.sampler, st.samplers);
  setOptions(ui.sky, st.skies);
  for (const [input, value] of [[ui.width, s.width], [ui.height, s.height], [ui.integrator, s.integrator],
      [ui.sampler, s.sampler], [ui.depth, s.max_depth], [ui.sky, s.sky], [ui.maxSpp, s.max_spp],
      [ui.exposure, s.exposure], [ui.tonemap, s.tonemap], [ui.errorMap, s.error_map], [ui.up, st.up],
      [ui.skyColor, toHex(s.sky_color, 1)], [ui.envPath, s.env_path], [ui.envRotate, s.env_rotate],
      [ui.envStrength, s.env_strength], [ui.envBackdrop, s.env_background !== null],
      [ui.sun, s.sun], [ui.sunRadius, s.sun_radius], [ui.lamp, s.lamp], [ui.lampAngle, s.lamp_angle],
      [ui.fog, s.fog], [ui.fogG, s.fog_g]]) setValue(input, value);
  if (s.env_background !== null) setValue(ui.envBackground, toHex(s.env_background, Math.max(1, ...s.env_background)));
  for (const [v, value] of [[ui.sunDirection, s.sun_direction], [ui.sunColor, s.sun_color],
      [ui.lampPosition, s.lamp_position], [ui.lampIntensity, s.lamp_intensity], [ui.lampDirection, s.lamp_direction],
      [ui.fogSigmaA, s.fog_sigma_a], [ui.fogSigmaS, s.fog_sigma_s]]) v.set(value);
  ui.exposureValue.textContent = `${Number(s.exposure).toFixed(1)} EV`;
  ui.skyColor.style.display = s.sky === "color" ? "" : "none";
  if (!ui.cmdTouched) { ui.cmdWidth.value = s.width; ui.cmdHeight.value = s.height; }   // follows the view
  if (st.camera) {
    setValue(ui.fov, st.camera.fov); setValue(ui.fovValue, st.camera.fov); setValue(ui.aperture, st.camera.aperture);
  }
  ui.saves.replaceChildren(...st.formats.map((f) =>
    h("button", { type: "button", class: `wspt-save-${f}`, onclick: () => send({ type: "save", format: f }) },
      f.toUpperCase())));
  view.params = st.params;
  const groups = [...new Set(st.params.map((p) => p.group))];
  setOptions(ui.group, groups);
  if (!groups.includes(view.group)) view.group = groups[0] || null;
  setValue(ui.group, view.group || "");
  showParams(ui, view, send);
}

function showParams(ui, view, send) {
  const rows = view.params.filter((p) => p.group === view.group).map((p) => {
    if (p.kind === "number") {
      const input = h("input", { type: "number", step: "0.01", value: String(p.value) });
      input.addEventListener("change", () => send({ type: "param", name: p.name, value: Number(input.value) }));
      return field(p.field, input);
    }
    const strength = Math.max(1, ...p.value);
    const colour = h("input", { type: "color", value: toHex(p.value, strength), title: p.value.join(" ") });
    const scale = h("input", { type: "number", min: "0", step: "0.1", value: String(strength), title: "strength" });
    const push = () => send({ type: "param", name: p.name, value: fromHex(colour.value, Number(scale.value)) });
    colour.addEventListener("input", push);
    scale.addEventListener("change", push);
    return field(p.field, h("span", {}, colour, " x ", scale));
  });
  ui.params.replaceChildren(...rows);
}

function toHex(rgb, strength) {
  return "#" + rgb.map((v) => Math.round(255 * Math.min(1, Math.max(0, v / strength)))
    .toString(16).padStart(2, "0")).join("");
}

function fromHex(hex, strength) {
  return [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16) / 255 * strength);
}

function notice(ui, text, level) {
  ui.notice.textContent = text;
  ui.notice.style.display = "block";
  ui.notice.style.color = level === "error" ? "#f99" : "#ddd";
  clearTimeout(ui.noticeTimer);
  ui.noticeTimer = setTimeout(() => { ui.notice.style.display = "none"; }, NOTICE_MS);
}

function showCommand(ui, message) {
  ui.command.value = message.text;
  ui.notes.textContent = message.notes.join("\n");
  const copied = navigator.clipboard ? navigator.clipboard.writeText(message.text) : Promise.reject();
  copied.then(() => notice(ui, "command line copied to the clipboard", "info"),
              () => notice(ui, "select the command below and copy it", "info"));
}

function download(message, buffer) {
  const url = URL.createObjectURL(new Blob([buffer], { type: message.mime }));
  const a = h("a", { href: url, download: message.name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
}

// ---------------------------------------------------------------- input

function wirePointer(ui, send) {
  const c = ui.canvas;
  let drag = null;          // {mode, x, y, dx, dy, queued}
  const fraction = (e) => { const r = c.getBoundingClientRect(); return [r.width, r.height]; };
  const flush = () => {
    if (drag && (drag.dx || drag.dy)) send({ type: drag.mode, dx: drag.dx, dy: drag.dy });
    if (drag) { drag.dx = drag.dy = 0; drag.queued = false; }
  };
  c.addEventListener("pointerdown", (e) => {
    ui.root.focus({ preventScroll: true });
    const mode = e.button === 0 && !e.shiftKey && !e.ctrlKey ? "orbit" : "pan";
    drag = { mode, x: e.clientX, y: e.clientY, dx: 0, dy: 0, queued: false };
    c.setPointerCapture(e.pointerId);
    c.classList.add("dragging");
    send({ type: "interact", active: true });
  });
  c.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const [w, hgt] = fraction(e);
    drag.dx += (e.clientX - drag.x) / w;
    drag.dy += (e.clientY - drag.y) / hgt;
    drag.x = e.clientX; drag.y = e.clientY;
    if (!drag.queued) { drag.queued = true; requestAnimationFrame(flush); }   // one message per display frame
  });
  const end = () => {
    if (!drag) return;
    flush();
    drag = null;
    c.classList.remove("dragging");
    send({ type: "interact", active: false });
  };
  c.addEventListener("pointerup", end);
  c.addEventListener("pointercancel", end);
  c.addEventListener("contextmenu", (e) => e.preventDefault());
  c.addEventListener("wheel", (e) => {
    e.preventDefault();
    const steps = -Math.sign(e.deltaY) * Math.min(3, Math.abs(e.deltaY) / 100 || 1);
    send({ type: e.ctrlKey || e.altKey ? "zoom" : "dolly", steps });
  }, { passive: false });
  c.addEventListener("dblclick", (e) => {
    const r = c.getBoundingClientRect();
    send({ type: "pick", x: (e.clientX - r.left) / r.width, y: (e.clientY - r.top) / r.height });
  });
}

function wireKeys(ui, view, send) {
  const orbit = (dx, dy) => send({ type: "orbit", dx, dy });
  const pan = (dx, dy) => send({ type: "pan", dx, dy });
  const o = ORBIT_KEY_STEP, p = PAN_KEY_STEP;
  ui.root.addEventListener("keydown", (e) => {
    if (/^(INPUT|SELECT|TEXTAREA)$/.test(e.target.tagName) || e.metaKey || e.ctrlKey || e.altKey) return;
    const k = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    const shift = e.shiftKey;
    const actions = {
      ArrowLeft: () => (shift ? pan(p, 0) : orbit(o, 0)), ArrowRight: () => (shift ? pan(-p, 0) : orbit(-o, 0)),
      ArrowUp: () => (shift ? pan(0, p) : orbit(0, o)), ArrowDown: () => (shift ? pan(0, -p) : orbit(0, -o)),
      a: () => pan(p, 0), d: () => pan(-p, 0), w: () => pan(0, p), s: () => pan(0, -p),
      "+": () => send({ type: "dolly", steps: 1 }), "=": () => send({ type: "dolly", steps: 1 }),
      "-": () => send({ type: "dolly", steps: -1 }), _: () => send({ type: "dolly", steps: -1 }),
      "]": () => send({ type: "zoom", steps: 1 }), "[": () => send({ type: "zoom", steps: -1 }),
      f: () => send({ type: "frame" }), r: () => send({ type: "reset" }),
      e: () => view.settings && send({ type: "set", key: "error_map", value: !view.settings.error_map }),
      u: () => send({ type: "up", axis: ui.up.value === "y" ? "z" : "y" }),
    };
    if (actions[k]) { actions[k](); e.preventDefault(); e.stopPropagation(); }
  });
}

function wireControls(ui, view, send) {
  const set = (key, value) => send({ type: "set", key, value });
  const on = (input, event, fn) => input.addEventListener(event, fn);
  on(ui.width, "change", () => set("width", Number(ui.width.value)));
  on(ui.height, "change", () => set("height", Number(ui.height.value)));
  on(ui.fov, "input", () => { ui.fovValue.value = ui.fov.value; set("fov", Number(ui.fov.value)); });
  on(ui.fovValue, "change", () => set("fov", Number(ui.fovValue.value)));
  on(ui.aperture, "change", () => set("aperture", Number(ui.aperture.value)));
  on(ui.up, "change", () => send({ type: "up", axis: ui.up.value }));
  on(ui.frame, "click", () => send({ type: "frame" }));
  on(ui.reset, "click", () => send({ type: "reset" }));
  on(ui.integrator, "change", () => set("integrator", ui.integrator.value));
  on(ui.sampler, "change", () => set("sampler", ui.sampler.value));
  on(ui.depth, "change", () => set("max_depth", Number(ui.depth.value)));
  on(ui.sky, "change", () => set("sky", ui.sky.value));
  on(ui.skyColor, "input", () => set("sky_color", fromHex(ui.skyColor.value, 1)));
  on(ui.envPath, "change", () => { set("env_path", ui.envPath.value); if (ui.envPath.value) set("sky", "environment"); });
  on(ui.envRotate, "change", () => set("env_rotate", Number(ui.envRotate.value)));
  on(ui.envStrength, "change", () => set("env_strength", Number(ui.envStrength.value)));
  const backdrop = () => set("env_background", ui.envBackdrop.checked ? fromHex(ui.envBackground.value, 1) : null);
  on(ui.envBackdrop, "change", backdrop);
  on(ui.envBackground, "input", () => { if (ui.envBackdrop.checked) backdrop(); });
  on(ui.sun, "change", () => set("sun", ui.sun.checked));
  on(ui.sunRadius, "change", () => set("sun_radius", Number(ui.sunRadius.value)));
  on(ui.lamp, "change", () => set("lamp", ui.lamp.value));
  on(ui.lampAngle, "change", () => set("lamp_angle", Number(ui.lampAngle.value)));
  on(ui.fog, "change", () => set("fog", ui.fog.checked));
  on(ui.fogG, "change", () => set("fog_g", Number(ui.fogG.value)));
  for (const [v, key] of [[ui.sunDirection, "sun_direction"], [ui.sunColor, "sun_color"],
      [ui.lampPosition, "lamp_position"], [ui.lampIntensity, "lamp_intensity"], [ui.lampDirection, "lamp_direction"],
      [ui.fogSigmaA, "fog_sigma_a"], [ui.fogSigmaS, "fog_sigma_s"]]) {
    for (const input of v.inputs) on(input, "change", () => set(key, v.get()));
  }
  on(ui.maxSpp, "change", () => set("max_spp", Number(ui.maxSpp.value)));
  on(ui.exposure, "input", () => set("exposure", Number(ui.exposure.value)));
  on(ui.tonemap, "change", () => set("tonemap", ui.tonemap.value));
  on(ui.errorMap, "change", () => set("error_map", ui.errorMap.checked));
  on(ui.group, "change", () => { view.group = ui.group.value; showParams(ui, view, send); });
  on(ui.reload, "click", () => send({ type: "reload" }));
  for (const input of [ui.cmdWidth, ui.cmdHeight]) on(input, "change", () => { ui.cmdTouched = true; });
  on(ui.copy, "click", () => send({ type: "command", width: Number(ui.cmdWidth.value) || null,
                                    height: Number(ui.cmdHeight.value) || null,
                                    spp: Number(ui.cmdSpp.value) || 64, out: ui.cmdOut.value }));
}
