// guide-sim view: fetches /state about once a second and draws it. The
// charts are SVG built here (no library, nothing from the internet); the
// state the test reads is mirrored in data-* attributes of <body>.
'use strict';

const NS = 'http://www.w3.org/2000/svg';
const POLL_MS = 1000;
const STAGE_COLORS = ['#d95f02', '#1b9e77', '#7570b3', '#e7298a', '#66a61e', '#e6ab02'];
// Counter names that are faults when not zero, in any group.
const FAULTY = /fault|fail|bad|lost|drop|overflow|cut|timeout|restart|non_finite/;

function el(name, attrs, parent) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function text(parent, x, y, s, attrs) {
  const t = el('text', Object.assign({ x, y, 'font-size': 11, 'font-family': 'sans-serif', fill: '#333' }, attrs), parent);
  t.textContent = s;
  return t;
}

// About n round ticks over [lo, hi].
function ticks(lo, hi, n) {
  const step0 = (hi - lo) / n;
  const mag = Math.pow(10, Math.floor(Math.log10(step0)));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= step0);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  return out;
}

// Ticks of a log axis: 1, 2, 5 times powers of ten.
function logTicks(lo, hi) {
  const out = [];
  for (let e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++) {
    for (const m of [1, 2, 5]) {
      const v = m * Math.pow(10, e);
      if (v >= lo && v <= hi) out.push(v);
    }
  }
  return out;
}

function fmt(v) {
  return Math.abs(v) >= 1000 || v === 0 ? v.toFixed(0) : +v.toPrecision(3) + '';
}

// Draws series {x, y, color, label, dots, width} and vertical marks
// {x, label, color} into svg; returns the number of points drawn.
function plot(svg, opt) {
  while (svg.firstChild) svg.removeChild(svg.firstChild);
  const W = +svg.getAttribute('width'), H = +svg.getAttribute('height');
  const m = { l: 52, r: 12, t: 24, b: 30 };
  el('rect', { x: 0, y: 0, width: W, height: H, fill: '#fff' }, svg);
  const fx = opt.xlog ? Math.log10 : (v) => v;
  let xs = [], ys = [];
  for (const s of opt.series) {
    s.x.forEach((x, i) => {
      const y = s.y[i];
      if (x !== null && y !== null && isFinite(fx(x))) { xs.push(fx(x)); ys.push(y); }
    });
  }
  svg.dataset.points = xs.length;
  if (xs.length < 2) {
    text(svg, W / 2, H / 2, opt.empty || 'waiting for data…', { 'text-anchor': 'middle', fill: '#888', 'font-size': 14 });
    return 0;
  }
  let [x0, x1] = [Math.min(...xs), Math.max(...xs)];
  let [y0, y1] = [Math.min(...ys, opt.yzero ? 0 : Infinity), Math.max(...ys, opt.yzero ? 0 : -Infinity)];
  if (x1 === x0) x1 = x0 + 1;
  if (y1 === y0) { y0 -= 1; y1 += 1; }
  const pad = (y1 - y0) * 0.05; y0 -= pad; y1 += pad;
  const X = (v) => m.l + (fx(v) - x0) / (x1 - x0) * (W - m.l - m.r);
  const Y = (v) => H - m.b - (v - y0) / (y1 - y0) * (H - m.t - m.b);
  const grid = { stroke: '#e4e4e4', 'stroke-width': 1 };
  const xt = opt.xlog ? logTicks(Math.pow(10, x0), Math.pow(10, x1)) : ticks(x0, x1, 6);
  for (const v of xt) {
    el('line', Object.assign({ x1: X(v), x2: X(v), y1: m.t, y2: H - m.b }, grid), svg);
    text(svg, X(v), H - m.b + 13, fmt(v), { 'text-anchor': 'middle' });
  }
  for (const v of ticks(y0, y1, 5)) {
    el('line', Object.assign({ x1: m.l, x2: W - m.r, y1: Y(v), y2: Y(v) }, grid), svg);
    text(svg, m.l - 4, Y(v) + 4, fmt(v), { 'text-anchor': 'end' });
  }
  if (y0 < 0 && y1 > 0) el('line', { x1: m.l, x2: W - m.r, y1: Y(0), y2: Y(0), stroke: '#999' }, svg);
  text(svg, W - m.r, H - 4, opt.xlabel, { 'text-anchor': 'end', fill: '#666' });
  text(svg, 4, 12, opt.ylabel, { fill: '#666' });
  for (const s of opt.series) {
    if (s.dots) {
      s.x.forEach((x, i) => {
        if (x !== null && s.y[i] !== null) el('circle', { cx: X(x), cy: Y(s.y[i]), r: 1.6, fill: s.color }, svg);
      });
    } else {
      let d = '';
      s.x.forEach((x, i) => {
        if (x === null || s.y[i] === null) return;
        d += (d ? 'L' : 'M') + X(x).toFixed(1) + ' ' + Y(s.y[i]).toFixed(1);
      });
      el('path', { d, fill: 'none', stroke: s.color, 'stroke-width': s.width || 1.3 }, svg);
    }
  }
  for (const mk of opt.marks || []) {
    if (fx(mk.x) < x0 || fx(mk.x) > x1) continue;
    el('line', { x1: X(mk.x), x2: X(mk.x), y1: m.t, y2: H - m.b, stroke: mk.color, 'stroke-dasharray': '4 3', 'stroke-width': 1.5 }, svg);
    // Labels on the side with room.
    const right = X(mk.x) < W / 2;
    text(svg, X(mk.x) + (right ? 3 : -3), m.t + 12 + 13 * (mk.row || 0), mk.label,
      { fill: mk.color, 'font-weight': 'bold', 'text-anchor': right ? 'start' : 'end' });
  }
  let lx = m.l + 6;
  for (const s of opt.series.filter((s) => s.label)) {
    el('rect', { x: lx, y: 8, width: 10, height: 4, fill: s.color }, svg);
    lx += 14 + text(svg, lx + 13, 13, s.label).getComputedTextLength() + 12;
  }
  return xs.length;
}

function stageLabel(k) {
  return k === 0 ? 'stage 1 (worm)' : 'stage ' + (k + 1);
}

function draw(s) {
  const t = s.time;
  plot(document.getElementById('chart-time'), {
    xlabel: 'board time, s', ylabel: 'arcsec',
    series: [
      { x: t.t, y: t.obs, color: '#bbb', label: 'gear error (no correction)', width: 5 },
      { x: t.t, y: t.applied, color: '#1f77b4', label: 'applied (pulses + feed-forward)' },
      { x: t.t, y: t.pointing, color: '#d62728', label: 'pointing error' },
      { x: t.t, y: t.pulse, color: '#2ca02c', label: 'guide pulses', dots: true },
    ],
  });
  const ph = s.phase;
  plot(document.getElementById('chart-phase'), ph ? {
    xlabel: 'gear phase, s (of ' + fmt(ph.period_s) + ' s)', ylabel: 'arcsec',
    series: [{ x: ph.points_x, y: ph.points_y, color: '#bbb', dots: true }]
      .concat(ph.stages.map((y, k) => ({ x: ph.x, y, color: STAGE_COLORS[k % 6], label: stageLabel(k) })))
      .concat([{ x: ph.x, y: ph.total, color: '#000', label: 'sum of the stages', width: 2.2 }]),
  } : { series: [], empty: 'waiting for a stage and a worm period of frames…' });
  const marks = s.stages.map((st, k) => ({
    x: st.period_s, color: STAGE_COLORS[k % 6], row: k,
    label: stageLabel(k) + ': ' + fmt(st.period_s) + ' s, gate ' + (st.gate_pm / 10).toFixed(0) + '%',
  }));
  plot(document.getElementById('chart-spectrum'), {
    xlog: true, xlabel: 'period, s', ylabel: 'arcsec', yzero: true, marks,
    series: [{ x: s.spectrum.period, y: s.spectrum.amp, color: '#333', label: 'amplitude', width: 1.6 }],
    empty: 'waiting for frames (the spectrum needs twice a period)…',
  });
  plot(document.getElementById('chart-learn'), {
    xlabel: 'board time, s', ylabel: 'learning %', yzero: true,
    series: [{ x: s.learn.t, y: s.learn.pm.map((v) => v / 10), color: '#6a3d9a', label: 'learning %', width: 2 }],
  });
  document.getElementById('learn-big').textContent = s.learn_pm === null ? '–' : 'learning ' + (s.learn_pm / 10).toFixed(1) + '%';
  drawTables(s);
  drawStatus(s);
  const b = document.body.dataset;
  b.link = s.link;
  b.frames = s.frames;
  b.learn = s.learn_pm === null ? '' : s.learn_pm;
  b.learnFirst = s.learn_first === null ? '' : s.learn_first;
  b.marks = s.stages.map((st) => st.period_s).join(',');
  b.gates = s.stages.map((st) => st.gate_pm).join(',');
  b.peaks = s.spectrum.peaks.map((p) => p[0]).join(',');
  b.problems = s.problems.length;
  b.linesBad = s.lines_bad;
  b.updates = +b.updates + 1;
}

function cell(row, v, cls) {
  const c = row.insertCell();
  c.textContent = v;
  if (cls) c.className = cls;
}

function drawTables(s) {
  const tb = document.getElementById('stages');
  tb.innerHTML = '<tr><th>stage</th><th>period, s</th><th>gate</th><th>fit amplitude, arcsec</th></tr>';
  s.stages.forEach((st, k) => {
    const r = tb.insertRow();
    cell(r, stageLabel(k));
    cell(r, fmt(st.period_s));
    cell(r, (st.gate_pm / 10).toFixed(0) + '%');
    cell(r, st.fit_amp === null ? '–' : st.fit_amp.toFixed(2));
  });
  if (s.phase) {
    const r = tb.insertRow();
    cell(r, 'fit leaves');
    r.insertCell().colSpan = 2;
    cell(r, s.phase.rms_after.toFixed(2) + ' of ' + s.phase.rms_before.toFixed(2) + ' rms');
  }
  const names = { L: 'learning (:~L#)', f: 'faults', l: 'learner', g: 'guiding', s: 'ST4', p: 'port' };
  const box = document.getElementById('counters');
  box.innerHTML = '';
  for (const g of ['f', 'L', 'l', 'g', 's', 'p']) {
    const list = s.counters[g];
    if (!list) continue;
    const div = document.createElement('div');
    div.className = 'group';
    const t = document.createElement('table');
    t.innerHTML = '<tr><th colspan="2"></th></tr>';
    t.rows[0].cells[0].textContent = names[g];
    for (const [k, v] of list) {
      const r = t.insertRow();
      const bad = (g === 'f' || FAULTY.test(k)) && v !== '0';
      cell(r, k);
      cell(r, v, bad ? 'fault' : g === 'f' ? 'ok' : '');
    }
    div.appendChild(t);
    box.appendChild(div);
  }
}

function drawStatus(s) {
  const who = document.getElementById('who');
  who.textContent = (s.product || '?') + ' ' + (s.version || '') + (s.reset ? ' (reset: ' + s.reset + ')' : '') +
    ' on ' + s.target + ': ' + s.link + ' · ' + s.frames + ' frames · view ' + s.view_version;
  const problems = s.problems.slice();
  if (s.lines_bad > 0 && s.last_bad) {
    problems.push(s.lines_bad + ' telemetry lines skipped; the last: "' + s.last_bad[0] + '" (' + s.last_bad[1] + ')');
  }
  showProblems(problems);
  document.getElementById('log').textContent = s.log.map(([t, m]) => t.toFixed(1) + ' s  ' + m).join('\n');
}

function showProblems(list) {
  const box = document.getElementById('problems');
  box.innerHTML = '';
  for (const p of list) {
    const d = document.createElement('div');
    d.textContent = p;
    box.appendChild(d);
  }
}

async function poll() {
  try {
    const r = await fetch('/state', { cache: 'no-store' });
    if (!r.ok) throw new Error('HTTP ' + r.status);
    draw(await r.json());
  } catch (e) {
    // The view itself stopped: say so, keep trying.
    document.body.dataset.link = 'view-gone';
    showProblems(['guide-sim view does not answer (' + e.message + '): is it still running?']);
  }
  setTimeout(poll, POLL_MS);
}

function svgText(id) {
  const svg = document.getElementById(id).cloneNode(true);
  svg.setAttribute('xmlns', NS);
  return new XMLSerializer().serializeToString(svg);
}

function download(blob, name) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

document.addEventListener('click', (ev) => {
  const b = ev.target;
  if (b.dataset.save) {
    download(new Blob([svgText(b.dataset.save)], { type: 'image/svg+xml' }), b.dataset.save + '.svg');
  } else if (b.dataset.png) {
    const svg = document.getElementById(b.dataset.png);
    const img = new Image();
    img.onload = () => {
      const c = document.createElement('canvas');
      c.width = 2 * svg.getAttribute('width');
      c.height = 2 * svg.getAttribute('height');
      const g = c.getContext('2d');
      g.scale(2, 2);
      g.drawImage(img, 0, 0);
      c.toBlob((blob) => download(blob, b.dataset.png + '.png'));
    };
    img.src = 'data:image/svg+xml;charset=utf-8,' + encodeURIComponent(svgText(b.dataset.png));
  }
});

poll();
