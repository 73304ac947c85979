// The style sheet and the scripts of the HTML reports (core/html_report.h), hand-written:
// canvas 2D only, no libraries, no network, so that the one file works offline.
//
// Test hooks (tests/report_browser_test.cpp): any script error, unhandled rejection,
// console.error or failed resource load is written into <pre id="eco-js-errors"> (visible at
// the top of the page, and in a dumped DOM); when every plot and scene has been drawn the
// body gets data-eco-ready="1", and each drawn canvas data-eco-rect="x,y,w,h" (CSS pixels,
// page coordinates) and data-eco-drawn (points or plants drawn).

namespace eco::html::assets {

extern const char* const kStyle;
extern const char* const kErrorTrap;
extern const char* const kScript;

const char* const kStyle = R"CSS(
body { font-family: "DejaVu Sans", system-ui, sans-serif; margin: 0 auto; max-width: 1180px; padding: 16px 24px 48px;
       color: #1d1d1d; background: #fff; line-height: 1.45; }
h1 { font-size: 1.6em; margin: 0.4em 0; } h2 { font-size: 1.3em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }
h3 { font-size: 1.1em; }
code, pre { font-family: "DejaVu Sans Mono", monospace; font-size: 0.86em; }
pre { background: #f6f6f4; padding: 8px 10px; overflow-x: auto; border: 1px solid #e4e4e0; }
.table-wrap { overflow-x: auto; }
table { border-collapse: collapse; margin: 8px 0 16px; font-size: 0.9em; }
th, td { border: 1px solid #d4d4d0; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #f0f0ec; } td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
td code { word-break: break-all; }
figure { margin: 12px 0 20px; } figure img { max-width: 100%; height: auto; border: 1px solid #e4e4e0; }
figcaption, .eco-caption { font-size: 0.85em; color: #555; }
.eco-errors { background: #fde8e8; color: #8a1010; border: 1px solid #e0a0a0; padding: 8px; white-space: pre-wrap; }
.eco-plot, .eco-scene { margin: 12px 0 24px; }
.eco-title { font-weight: bold; margin-bottom: 4px; }
.eco-controls { font-size: 0.85em; margin: 4px 0; display: flex; gap: 14px; flex-wrap: wrap; align-items: center; }
.eco-controls button { font-size: 0.95em; padding: 1px 8px; }
.eco-canvas { display: block; width: 100%; border: 1px solid #d4d4d0; cursor: crosshair; touch-action: none; }
.eco-scene .eco-canvas { cursor: grab; }
.eco-legend { font-size: 0.82em; display: flex; flex-wrap: wrap; gap: 2px 14px; margin-top: 4px; }
.eco-legend label { cursor: pointer; white-space: nowrap; }
.eco-swatch { display: inline-block; width: 12px; height: 12px; margin: 0 4px -1px 2px; border: 1px solid rgba(0,0,0,0.3); }
.eco-readout { font-size: 0.82em; color: #333; min-height: 1.4em; font-family: "DejaVu Sans Mono", monospace; }
.eco-help { font-size: 0.8em; color: #666; }
)CSS";

const char* const kErrorTrap = R"JS(
(function () {
  function mark(text) {
    var host = document.body || document.documentElement;
    var el = document.getElementById('eco-js-errors');
    if (!el) {
      el = document.createElement('pre');
      el.id = 'eco-js-errors';
      el.className = 'eco-errors';
      host.insertBefore(el, host.firstChild);
    }
    el.textContent += 'report error: ' + text + '\n';
  }
  window.ecoMarkError = mark;
  window.addEventListener('error', function (e) {
    if (e.target && e.target !== window && e.target.tagName) mark('could not load ' + e.target.tagName.toLowerCase());
    else mark((e.message || 'script error') + ' (line ' + (e.lineno || '?') + ')');
  }, true);
  window.addEventListener('unhandledrejection', function (e) { mark('unhandled rejection: ' + e.reason); });
  var consoleError = console.error;
  console.error = function () {
    mark(Array.prototype.join.call(arguments, ' '));
    return consoleError.apply(console, arguments);
  };
})();
)JS";

const char* const kScript = R"JS(
(function () {
'use strict';
var dpr = Math.max(1, window.devicePixelRatio || 1);

function el(tag, cls, text) {
  var e = document.createElement(tag);
  if (cls) e.className = cls;
  if (text !== undefined) e.textContent = text;
  return e;
}
function fmt(v) {
  if (v === null || !isFinite(v)) return '-';
  var a = Math.abs(v);
  if (a !== 0 && (a >= 1e6 || a < 1e-3)) return v.toExponential(2);
  return String(Math.round(v * 1000) / 1000);
}
// Ticks at 1, 2 or 5 x 10^k covering [lo, hi], about `n` of them.
function niceTicks(lo, hi, n) {
  if (!(hi > lo)) { hi = lo + 1; }
  var raw = (hi - lo) / Math.max(1, n), p = Math.pow(10, Math.floor(Math.log10(raw))), m = raw / p;
  var step = (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p, ticks = [];
  for (var t = Math.ceil(lo / step - 1e-9) * step; t <= hi + step * 1e-9; t += step) ticks.push(Math.abs(t) < step * 1e-9 ? 0 : t);
  return ticks;
}
function markDrawn(canvas, count) {
  var r = canvas.getBoundingClientRect();
  canvas.setAttribute('data-eco-rect', [Math.round(r.left + window.scrollX), Math.round(r.top + window.scrollY),
                                        Math.round(r.width), Math.round(r.height)].join(','));
  canvas.setAttribute('data-eco-drawn', String(count));
}
function sizeCanvas(canvas, cssHeight) {
  var w = Math.max(200, canvas.clientWidth || canvas.parentNode.clientWidth || 800);
  canvas.style.height = cssHeight + 'px';
  canvas.width = Math.round(w * dpr);
  canvas.height = Math.round(cssHeight * dpr);
  return { w: w, h: cssHeight };
}
function schedule(state, draw) {
  if (state.pending) return;
  state.pending = true;
  window.requestAnimationFrame(function () { state.pending = false; draw(); });
}

// ------------------------------------------------------------------ line plots
function ecoPlot(root, spec) {
  var state = { group: 0, hidden: {}, xRange: null, logY: false, hoverX: null, drag: null, pending: false };
  root.appendChild(el('div', 'eco-title', spec.title));
  var controls = el('div', 'eco-controls');
  root.appendChild(controls);
  if (spec.groups.length > 1) {
    var label = el('label', '', 'show ');
    var select = el('select');
    spec.groups.forEach(function (g, i) { var o = el('option', '', g.name); o.value = String(i); select.appendChild(o); });
    select.addEventListener('change', function () { state.group = +select.value; state.xRange = null; buildLegend(); draw(); });
    label.appendChild(select);
    controls.appendChild(label);
  }
  if (spec.logYToggle) {
    var logLabel = el('label'), box = el('input');
    box.type = 'checkbox';
    box.addEventListener('change', function () { state.logY = box.checked; draw(); });
    logLabel.appendChild(box);
    logLabel.appendChild(document.createTextNode(' log y'));
    controls.appendChild(logLabel);
  }
  controls.appendChild(el('span', 'eco-help', 'drag: zoom into an x range; double-click: whole range; legend: show or hide a line'));
  var canvas = el('canvas', 'eco-canvas');
  root.appendChild(canvas);
  var legend = el('div', 'eco-legend');
  root.appendChild(legend);
  var readout = el('div', 'eco-readout');
  root.appendChild(readout);
  var M = { l: 70, r: 16, t: 12, b: 46 }, frame = null;

  function group() { return spec.groups[state.group] || { name: '', series: [] }; }
  function visible() { return group().series.filter(function (s) { return !state.hidden[s.name]; }); }
  function buildLegend() {
    legend.textContent = '';
    group().series.forEach(function (s) {
      var l = el('label'), box = el('input'), sw = el('span', 'eco-swatch');
      box.type = 'checkbox';
      box.checked = !state.hidden[s.name];
      box.addEventListener('change', function () { state.hidden[s.name] = !box.checked; draw(); });
      sw.style.background = s.colour;
      if (s.dashed) sw.style.background = 'repeating-linear-gradient(90deg,' + s.colour + ' 0 3px, #fff 3px 5px)';
      l.appendChild(box); l.appendChild(sw); l.appendChild(document.createTextNode(s.name));
      legend.appendChild(l);
    });
  }
  function extent(series) {
    var xlo = Infinity, xhi = -Infinity, ylo = Infinity, yhi = -Infinity;
    series.forEach(function (s) { for (var i = 0; i < s.x.length; i++) if (s.x[i] !== null) { xlo = Math.min(xlo, s.x[i]); xhi = Math.max(xhi, s.x[i]); } });
    if (state.xRange) { xlo = state.xRange[0]; xhi = state.xRange[1]; }
    series.forEach(function (s) {
      for (var i = 0; i < s.x.length; i++) {
        var x = s.x[i], y = s.y[i];
        if (x === null || y === null || x < xlo || x > xhi || (state.logY && y <= 0)) continue;
        ylo = Math.min(ylo, y); yhi = Math.max(yhi, y);
      }
    });
    if (spec.referenceY !== undefined && !(state.logY && spec.referenceY <= 0)) { ylo = Math.min(ylo, spec.referenceY); yhi = Math.max(yhi, spec.referenceY); }
    if (!isFinite(xlo)) { xlo = 0; xhi = 1; }
    if (xhi === xlo) { xlo -= 0.5; xhi += 0.5; }
    if (!isFinite(ylo)) { ylo = state.logY ? 1 : 0; yhi = state.logY ? 10 : 1; }
    if (!state.logY) { ylo = Math.min(0, ylo); yhi = yhi > ylo ? yhi + (yhi - ylo) * 0.04 : ylo + 1; }
    else { ylo = Math.pow(10, Math.floor(Math.log10(ylo))); yhi = Math.pow(10, Math.ceil(Math.log10(yhi) + 1e-9)); if (yhi <= ylo) yhi = ylo * 10; }
    return { xlo: xlo, xhi: xhi, ylo: ylo, yhi: yhi };
  }
  function draw() {
    var size = sizeCanvas(canvas, 340), ctx = canvas.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = '#fff';
    ctx.fillRect(0, 0, size.w, size.h);
    var series = visible(), e = extent(series);
    var pw = size.w - M.l - M.r, ph = size.h - M.t - M.b;
    var ty = state.logY ? function (v) { return Math.log10(v); } : function (v) { return v; };
    var y0 = ty(e.ylo), y1 = ty(e.yhi);
    var X = function (x) { return M.l + (x - e.xlo) / (e.xhi - e.xlo) * pw; };
    var Y = function (y) { return M.t + ph - (ty(y) - y0) / (y1 - y0) * ph; };
    frame = { e: e, pw: pw, ph: ph, X: X };
    ctx.font = '11px "DejaVu Sans", sans-serif';
    ctx.lineWidth = 1;
    ctx.textAlign = 'center'; ctx.textBaseline = 'top'; ctx.fillStyle = '#333';
    niceTicks(e.xlo, e.xhi, Math.max(2, Math.floor(pw / 90))).forEach(function (t) {
      var px = X(t);
      ctx.strokeStyle = '#e6e6e6'; ctx.beginPath(); ctx.moveTo(px + 0.5, M.t); ctx.lineTo(px + 0.5, M.t + ph); ctx.stroke();
      ctx.fillText(fmt(t), px, M.t + ph + 5);
    });
    var yt = [];
    if (state.logY) { for (var p = y0; p <= y1 + 1e-9; p++) yt.push(Math.pow(10, p)); }
    else yt = niceTicks(e.ylo, e.yhi, Math.max(2, Math.floor(ph / 50)));
    ctx.textAlign = 'right'; ctx.textBaseline = 'middle';
    yt.forEach(function (t) {
      var py = Y(t);
      if (py < M.t - 0.5 || py > M.t + ph + 0.5) return;
      ctx.strokeStyle = '#e6e6e6'; ctx.beginPath(); ctx.moveTo(M.l, py + 0.5); ctx.lineTo(M.l + pw, py + 0.5); ctx.stroke();
      ctx.fillText(fmt(t), M.l - 6, py);
    });
    ctx.strokeStyle = '#555'; ctx.strokeRect(M.l + 0.5, M.t + 0.5, pw, ph);
    ctx.textAlign = 'center'; ctx.textBaseline = 'bottom'; ctx.fillStyle = '#222';
    ctx.fillText(spec.xLabel, M.l + pw / 2, size.h - 4);
    ctx.save(); ctx.translate(14, M.t + ph / 2); ctx.rotate(-Math.PI / 2); ctx.textBaseline = 'middle';
    ctx.fillText(spec.yLabel, 0, 0); ctx.restore();
    ctx.save();
    ctx.beginPath(); ctx.rect(M.l, M.t, pw, ph); ctx.clip();
    if (spec.referenceY !== undefined && !(state.logY && spec.referenceY <= 0)) {
      ctx.strokeStyle = '#999'; ctx.setLineDash([4, 4]);
      ctx.beginPath(); ctx.moveTo(M.l, Y(spec.referenceY)); ctx.lineTo(M.l + pw, Y(spec.referenceY)); ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = '#777'; ctx.textAlign = 'right'; ctx.textBaseline = 'bottom';
      ctx.fillText(spec.referenceLabel || '', M.l + pw - 4, Y(spec.referenceY) - 2);
    }
    var points = 0;
    series.forEach(function (s) {
      ctx.strokeStyle = s.colour; ctx.fillStyle = s.colour; ctx.lineWidth = 1.8;
      ctx.setLineDash(s.dashed ? [6, 4] : []);
      ctx.beginPath();
      var open = false;
      for (var i = 0; i < s.x.length; i++) {
        var x = s.x[i], y = s.y[i];
        if (x === null || y === null || (state.logY && y <= 0)) { open = false; continue; }
        if (open) ctx.lineTo(X(x), Y(y)); else ctx.moveTo(X(x), Y(y));
        open = true;
        points++;
      }
      ctx.stroke();
      ctx.setLineDash([]);
      if (s.x.length <= 40) for (var k = 0; k < s.x.length; k++) {
        if (s.x[k] === null || s.y[k] === null || (state.logY && s.y[k] <= 0)) continue;
        ctx.beginPath(); ctx.arc(X(s.x[k]), Y(s.y[k]), 2.2, 0, 2 * Math.PI); ctx.fill();
      }
    });
    if (state.drag && Math.abs(state.drag.x1 - state.drag.x0) > 2) {
      ctx.fillStyle = 'rgba(60,110,200,0.15)';
      ctx.fillRect(Math.min(state.drag.x0, state.drag.x1), M.t, Math.abs(state.drag.x1 - state.drag.x0), ph);
    }
    if (state.hoverX !== null) {
      ctx.strokeStyle = 'rgba(0,0,0,0.35)'; ctx.lineWidth = 1;
      ctx.beginPath(); ctx.moveTo(state.hoverX + 0.5, M.t); ctx.lineTo(state.hoverX + 0.5, M.t + ph); ctx.stroke();
    }
    ctx.restore();
    markDrawn(canvas, points);
    updateReadout();
  }
  function updateReadout() {
    if (state.hoverX === null || !frame) { readout.textContent = '\u00a0'; return; }
    var x = frame.e.xlo + (state.hoverX - M.l) / frame.pw * (frame.e.xhi - frame.e.xlo), parts = [];
    visible().forEach(function (s) {
      var best = -1, bd = Infinity;
      for (var i = 0; i < s.x.length; i++) if (s.x[i] !== null) { var d = Math.abs(s.x[i] - x); if (d < bd) { bd = d; best = i; } }
      if (best >= 0) parts.push(s.name + ' ' + fmt(s.y[best]) + ' at ' + fmt(s.x[best]));
    });
    readout.textContent = spec.xLabel + ' ' + fmt(x) + ' | ' + parts.join(' | ');
  }
  function localX(ev) { var r = canvas.getBoundingClientRect(); return ev.clientX - r.left; }
  canvas.addEventListener('pointerdown', function (ev) { var x = localX(ev); state.drag = { x0: x, x1: x }; canvas.setPointerCapture(ev.pointerId); });
  canvas.addEventListener('pointermove', function (ev) {
    var x = localX(ev);
    state.hoverX = frame && x >= M.l && x <= M.l + frame.pw ? x : null;
    if (state.drag) state.drag.x1 = x;
    schedule(state, draw);
  });
  canvas.addEventListener('pointerup', function () {
    if (state.drag && frame && Math.abs(state.drag.x1 - state.drag.x0) > 5) {
      var e = frame.e, f = function (px) { return e.xlo + (Math.min(Math.max(px, M.l), M.l + frame.pw) - M.l) / frame.pw * (e.xhi - e.xlo); };
      var a = f(Math.min(state.drag.x0, state.drag.x1)), b = f(Math.max(state.drag.x0, state.drag.x1));
      if (b > a) state.xRange = [a, b];
    }
    state.drag = null;
    schedule(state, draw);
  });
  canvas.addEventListener('pointerleave', function () { state.hoverX = null; schedule(state, draw); });
  canvas.addEventListener('dblclick', function () { state.xRange = null; schedule(state, draw); });
  window.addEventListener('resize', function () { schedule(state, draw); });
  buildLegend();
  draw();
}

// ------------------------------------------------------------------ scene top view
function decode(b64, Type) {
  var bin = atob(b64), bytes = new Uint8Array(bin.length);
  for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return new Type(bytes.buffer, 0, bytes.length / Type.BYTES_PER_ELEMENT);
}
function rgb(hex) { return [parseInt(hex.substr(1, 2), 16), parseInt(hex.substr(3, 2), 16), parseInt(hex.substr(5, 2), 16)]; }

function ecoScene(root, spec) {
  var n = spec.n, nCanopy = spec.nCanopy, nUnder = n - nCanopy;
  var qx = decode(spec.x, Uint16Array), qy = decode(spec.y, Uint16Array), qr = decode(spec.r, Uint16Array);
  var qh = decode(spec.h, Uint16Array), sp = decode(spec.s, Uint8Array);
  // Positions: 16-bit steps over the quantization rectangle q (which holds every plant).
  var sx = (spec.qx1 - spec.qx0) / 65535, sy = (spec.qy1 - spec.qy0) / 65535;
  var X = new Float32Array(n), Y = new Float32Array(n), R = new Float32Array(n);
  for (var i = 0; i < n; i++) { X[i] = spec.qx0 + qx[i] * sx; Y[i] = spec.qy0 + qy[i] * sy; R[i] = qr[i] / 100; }
  var nSpecies = spec.species.length, visibleSpecies = new Uint8Array(256), counts = new Int32Array(256);
  for (i = 0; i < 256; i++) visibleSpecies[i] = 1;
  for (i = 0; i < n; i++) counts[sp[i]]++;
  // Packed RGBA (little-endian) per species for the pixel stamps; unknown ids grey.
  var packed = new Uint32Array(256), cols = [];
  for (i = 0; i < 256; i++) {
    var c = i < nSpecies ? rgb(spec.species[i].colour) : [150, 150, 150];
    cols.push(c);
    packed[i] = (255 << 24 | c[2] << 16 | c[1] << 8 | c[0]) >>> 0;
  }
  // A uniform grid per layer (counting sort of plant indices by cell): a frame visits only
  // the cells in view, widened by the layer's largest crown.
  function buildGrid(first, last) {
    var count = last - first, g = Math.max(1, Math.min(1024, Math.round(Math.sqrt(count / 8))));
    var cw = (spec.qx1 - spec.qx0) / g || 1, ch = (spec.qy1 - spec.qy0) / g || 1;
    var start = new Uint32Array(g * g + 1), order = new Uint32Array(count), cell = new Uint32Array(count), maxR = 0;
    for (var k = 0; k < count; k++) {
      var p = first + k;
      var cx = Math.min(g - 1, Math.max(0, Math.floor((X[p] - spec.qx0) / cw))), cy = Math.min(g - 1, Math.max(0, Math.floor((Y[p] - spec.qy0) / ch)));
      cell[k] = cy * g + cx; start[cell[k] + 1]++;
      if (R[p] > maxR) maxR = R[p];
    }
    for (k = 0; k < g * g; k++) start[k + 1] += start[k];
    var fill = start.slice(0, g * g);
    for (k = 0; k < count; k++) order[fill[cell[k]]++] = first + k;
    return { g: g, cw: cw, ch: ch, start: start, order: order, maxR: maxR };
  }
  var layers = [{ name: 'undergrowth', grid: buildGrid(0, nUnder), on: true, count: nUnder },
                { name: 'canopy', grid: buildGrid(nUnder, n), on: true, count: nCanopy }];

  root.appendChild(el('div', 'eco-title', spec.title));
  var controls = el('div', 'eco-controls');
  root.appendChild(controls);
  var state = { cx: 0, cy: 0, scale: 1, fitScale: 1, pending: false, drag: null, drawMs: 0 };
  function button(text, action) { var b = el('button', '', text); b.type = 'button'; b.addEventListener('click', action); controls.appendChild(b); }
  button('+', function () { zoomAt(null, 1.6); });
  button('\u2212', function () { zoomAt(null, 1 / 1.6); });
  button('whole scene', function () { fit(); schedule(state, draw); });
  layers.forEach(function (layer) {
    var l = el('label'), box = el('input');
    box.type = 'checkbox'; box.checked = true;
    box.addEventListener('change', function () { layer.on = box.checked; schedule(state, draw); });
    l.appendChild(box); l.appendChild(document.createTextNode(' ' + layer.name + ' (' + layer.count.toLocaleString('en') + ')'));
    controls.appendChild(l);
  });
  controls.appendChild(el('span', 'eco-help', 'wheel or +/\u2212: zoom; drag: pan; double-click: whole scene'));
  var canvas = el('canvas', 'eco-canvas');
  root.appendChild(canvas);
  var legend = el('div', 'eco-legend');
  root.appendChild(legend);
  for (var s = 0; s < nSpecies; s++) {
    if (!counts[s]) continue;
    (function (s) {
      var l = el('label'), box = el('input'), sw = el('span', 'eco-swatch');
      box.type = 'checkbox'; box.checked = true;
      box.addEventListener('change', function () { visibleSpecies[s] = box.checked ? 1 : 0; schedule(state, draw); });
      sw.style.background = spec.species[s].colour;
      l.appendChild(box); l.appendChild(sw); l.appendChild(document.createTextNode(spec.species[s].name + ' (' + counts[s].toLocaleString('en') + ')'));
      legend.appendChild(l);
    })(s);
  }
  var readout = el('div', 'eco-readout', '\u00a0');
  root.appendChild(readout);
  var size = null;

  function fit() {
    var w = spec.x1 - spec.x0, h = spec.y1 - spec.y0;
    state.fitScale = Math.min(size.w / (w || 1), size.h / (h || 1)) * 0.98;
    state.scale = state.fitScale;
    state.cx = spec.x0 + w / 2; state.cy = spec.y0 + h / 2;
  }
  function zoomAt(ev, factor) {
    var r = canvas.getBoundingClientRect();
    var px = ev ? ev.clientX - r.left : size.w / 2, py = ev ? ev.clientY - r.top : size.h / 2;
    var wx = state.cx + (px - size.w / 2) / state.scale, wy = state.cy - (py - size.h / 2) / state.scale;
    state.scale = Math.min(Math.max(state.scale * factor, state.fitScale * 0.5), 400);
    state.cx = wx - (px - size.w / 2) / state.scale; state.cy = wy + (py - size.h / 2) / state.scale;
    schedule(state, draw);
  }
  // Each visible cell of a layer: call visit(p) for every plant index in it.
  function eachInView(layer, wx0, wy0, wx1, wy1, visit) {
    var G = layer.grid, m = G.maxR;
    var gx0 = Math.max(0, Math.floor((wx0 - m - spec.qx0) / G.cw)), gx1 = Math.min(G.g - 1, Math.floor((wx1 + m - spec.qx0) / G.cw));
    var gy0 = Math.max(0, Math.floor((wy0 - m - spec.qy0) / G.ch)), gy1 = Math.min(G.g - 1, Math.floor((wy1 + m - spec.qy0) / G.ch));
    for (var gy = gy0; gy <= gy1; gy++)
      for (var gx = gx0; gx <= gx1; gx++) {
        var c = gy * G.g + gx;
        for (var k = G.start[c]; k < G.start[c + 1]; k++) visit(G.order[k]);
      }
  }
  function draw() {
    var t0 = performance.now();
    var W = canvas.width, H = canvas.height, ctx = canvas.getContext('2d');
    var k = state.scale * dpr;  // device pixels per metre
    var hw = size.w / 2 / state.scale, hh = size.h / 2 / state.scale;
    var wx0 = state.cx - hw, wx1 = state.cx + hw, wy0 = state.cy - hh, wy1 = state.cy + hh;
    var ox = W / 2 - state.cx * k, oy = H / 2 + state.cy * k;  // px = ox + x k, py = oy - y k
    // Pass 1: small plants (under 2.5 device pixels of crown) as pixel stamps into one image.
    var img = ctx.createImageData(W, H), buf = new Uint32Array(img.data.buffer);
    buf.fill(0xffeaf1f3);  // background #f3f1ea
    var sceneX0 = Math.round(ox + spec.x0 * k), sceneX1 = Math.round(ox + spec.x1 * k);
    var sceneY0 = Math.round(oy - spec.y1 * k), sceneY1 = Math.round(oy - spec.y0 * k);
    for (var yy = Math.max(0, sceneY0); yy < Math.min(H, sceneY1); yy++)
      buf.fill(0xffffffff, yy * W + Math.max(0, sceneX0), yy * W + Math.min(W, sceneX1));
    var big = [], drawn = 0;
    function stamp(p) {
      if (!visibleSpecies[sp[p]]) return;
      var rp = R[p] * k;
      if (rp >= 2.5) { big.push(p); return; }
      var px = Math.round(ox + X[p] * k), py = Math.round(oy - Y[p] * k), col = packed[sp[p]], rr = rp < 0.8 ? 0 : Math.round(rp);
      for (var dy = -rr; dy <= rr; dy++) {
        var yq = py + dy;
        if (yq < 0 || yq >= H) continue;
        var span = Math.floor(Math.sqrt(rr * rr - dy * dy + 0.5));
        var a = Math.max(0, px - span), b = Math.min(W - 1, px + span), row = yq * W;
        for (var xq = a; xq <= b; xq++) buf[row + xq] = col;
      }
      drawn++;
    }
    if (layers[0].on) eachInView(layers[0], wx0, wy0, wx1, wy1, stamp);
    ctx.putImageData(img, 0, 0);
    // Pass 2: larger undergrowth crowns as discs, one path per species.
    function discs(list, alpha, outline) {
      var bySpecies = {};
      list.forEach(function (p) { (bySpecies[sp[p]] = bySpecies[sp[p]] || []).push(p); });
      ctx.globalAlpha = alpha;
      Object.keys(bySpecies).forEach(function (s) {
        var c = cols[+s];
        ctx.fillStyle = 'rgb(' + c[0] + ',' + c[1] + ',' + c[2] + ')';
        ctx.beginPath();
        bySpecies[s].forEach(function (p) {
          var px = ox + X[p] * k, py = oy - Y[p] * k, rp = Math.max(R[p] * k, 0.8);
          ctx.moveTo(px + rp, py); ctx.arc(px, py, rp, 0, 2 * Math.PI);
        });
        ctx.fill();
        if (outline) { ctx.globalAlpha = 0.5; ctx.strokeStyle = 'rgba(30,30,30,0.7)'; ctx.lineWidth = Math.max(1, dpr * 0.8); ctx.stroke(); ctx.globalAlpha = alpha; }
      });
      ctx.globalAlpha = 1;
      drawn += list.length;
    }
    discs(big, 0.9, false);
    // Pass 3: canopy crowns above, half transparent, outlined.
    if (layers[1].on) {
      var canopy = [];
      eachInView(layers[1], wx0, wy0, wx1, wy1, function (p) { if (visibleSpecies[sp[p]]) canopy.push(p); });
      discs(canopy, 0.45, true);
    }
    drawScaleBar(ctx, k);
    state.drawMs = performance.now() - t0;
    canvas.setAttribute('data-eco-draw-ms', state.drawMs.toFixed(1));
    markDrawn(canvas, drawn);
  }
  function drawScaleBar(ctx, k) {
    var target = 120 * dpr / k, p = Math.pow(10, Math.floor(Math.log10(target))), m = target / p;
    var len = (m < 2 ? 1 : m < 5 ? 2 : 5) * p, px = len * k, x = 12 * dpr, y = canvas.height - 14 * dpr;
    ctx.fillStyle = 'rgba(255,255,255,0.8)';
    ctx.fillRect(x - 6 * dpr, y - 18 * dpr, px + 12 * dpr + 60 * dpr, 28 * dpr);
    ctx.fillStyle = '#222';
    ctx.fillRect(x, y - 3 * dpr, px, 4 * dpr);
    ctx.font = Math.round(11 * dpr) + 'px "DejaVu Sans", sans-serif';
    ctx.textBaseline = 'bottom'; ctx.textAlign = 'left';
    ctx.fillText(fmt(len) + ' m', x + px + 6 * dpr, y + 2 * dpr);
  }
  function plantAt(wx, wy) {
    var best = -1, bestD = Infinity;
    for (var L = 1; L >= 0; L--) {
      if (!layers[L].on) continue;
      eachInView(layers[L], wx, wy, wx, wy, function (p) {
        if (!visibleSpecies[sp[p]]) return;
        var dx = X[p] - wx, dy = Y[p] - wy, d = Math.sqrt(dx * dx + dy * dy), r = Math.max(R[p], 1.5 / state.scale);
        if (d <= r && d / r < bestD) { bestD = d / r; best = p; }
      });
      if (best >= 0) return best;
    }
    return best;
  }
  function world(ev) {
    var r = canvas.getBoundingClientRect();
    return [state.cx + (ev.clientX - r.left - size.w / 2) / state.scale, state.cy - (ev.clientY - r.top - size.h / 2) / state.scale];
  }
  canvas.addEventListener('wheel', function (ev) { ev.preventDefault(); zoomAt(ev, Math.pow(1.0015, -ev.deltaY)); }, { passive: false });
  canvas.addEventListener('pointerdown', function (ev) {
    state.drag = { x: ev.clientX, y: ev.clientY, cx: state.cx, cy: state.cy };
    canvas.setPointerCapture(ev.pointerId);
  });
  canvas.addEventListener('pointermove', function (ev) {
    if (state.drag) {
      state.cx = state.drag.cx - (ev.clientX - state.drag.x) / state.scale;
      state.cy = state.drag.cy + (ev.clientY - state.drag.y) / state.scale;
      schedule(state, draw);
      return;
    }
    var w = world(ev), p = plantAt(w[0], w[1]), text = 'x ' + w[0].toFixed(1) + ' m, y ' + w[1].toFixed(1) + ' m';
    if (p >= 0) text += ' | ' + (p >= nUnder ? 'canopy ' : 'undergrowth ') + (spec.species[sp[p]] ? spec.species[sp[p]].name : 'species ' + sp[p]) +
                        ', height ' + (qh[p] / 100).toFixed(2) + ' m, crown radius ' + R[p].toFixed(2) + ' m';
    readout.textContent = text + ' | drawn in ' + state.drawMs.toFixed(0) + ' ms';
  });
  canvas.addEventListener('pointerup', function () { state.drag = null; });
  canvas.addEventListener('dblclick', function () { fit(); schedule(state, draw); });
  window.addEventListener('resize', function () { size = sizeCanvas(canvas, size.h); schedule(state, draw); });
  var aspect = (spec.y1 - spec.y0) / ((spec.x1 - spec.x0) || 1);
  var width0 = Math.max(200, canvas.clientWidth || root.clientWidth || 800);
  size = sizeCanvas(canvas, Math.round(Math.min(760, Math.max(240, width0 * aspect))));
  fit();
  draw();
}

var all = document.querySelectorAll('.eco-plot, .eco-scene');
for (var i = 0; i < all.length; i++) {
  try {
    var spec = JSON.parse(all[i].querySelector('script').textContent);
    if (all[i].classList.contains('eco-plot')) ecoPlot(all[i], spec); else ecoScene(all[i], spec);
  } catch (e) {
    window.ecoMarkError((all[i].id || 'widget') + ': ' + (e && e.stack ? e.stack : e));
  }
}
document.body.setAttribute('data-eco-ready', '1');
// Pictures decoded after the first draw may move the canvases: their rectangles again.
window.addEventListener('load', function () {
  var drawn = document.querySelectorAll('canvas[data-eco-rect]');
  for (var i = 0; i < drawn.length; i++) markDrawn(drawn[i], drawn[i].getAttribute('data-eco-drawn'));
});
})();
)JS";

}  // namespace eco::html::assets
