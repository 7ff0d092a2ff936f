// The hand studio page: skin.glb from the server, a slider per DOF, the posture solver behind
// `POST /api/solve` (docs/studio.md). Bundled with three.js by esbuild at build time.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { LinearPostureSolver, JointPoser } from './solver.js';

const view = document.getElementById('view');
const status = document.getElementById('status');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f4f6);
scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 1.6));
const camera = new THREE.PerspectiveCamera(30, 1, 0.01, 10);
// The key light moves with the camera (upper left of the view), so every view is lit.
const key = new THREE.DirectionalLight(0xffffff, 2.2);
key.position.set(-0.4, 0.5, 1);
camera.add(key);
scene.add(camera);
const controls = new OrbitControls(camera, renderer.domElement);

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', () => { resize(); requestRender(); });

// Drawn on demand: a frame when something moved (a solve's answer, the camera, the piano's
// easing, playback), not continuously, so that a software renderer leaves the page's thread to
// the sliders. redrawStart is the first slider move since the last frame: the frame that shows
// the answer records the time from that move to the hand drawn (state.redrawMs).
function requestRender() {
  if (state.frameRequested) return;
  state.frameRequested = true;
  requestAnimationFrame(drawFrame);
}
function drawFrame() {
  state.frameRequested = false;
  controls.update();
  if (piano.on && easeBones()) requestRender();
  renderer.render(scene, camera);
  if (state.redrawStart !== null && state.answered) {
    renderer.getContext().finish();  // the picture is drawn, not only queued
    state.lastRedrawMs = performance.now() - state.redrawStart;
    state.redrawMs.push(state.lastRedrawMs);
    state.redrawStart = null;
    state.answered = false;
    status.textContent = `redrawn ${state.lastRedrawMs.toFixed(1)} ms after the slider (solved in the ${state.lastSolvedIn} in ${state.lastSolveMs.toFixed(2)} ms), potential ${state.lastEnergy.toFixed(2)}`;
  }
}

const state = { dofs: [], values: {}, mode: {}, bones: {}, centre: new THREE.Vector3(), radius: 0.15, pending: null, busy: false,
                solveIn: 'page', local: {}, poser: null, redrawStart: null, answered: false, redrawMs: [], frameRequested: false };
window.studio = state;  // for tests and the console

async function api(path, body) {
  const r = await fetch(path, body ? { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) } : {});
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || ('HTTP ' + r.status));
  return j;
}

function setView(name) {
  // The glb's root turns the palm frame (Z out of the palm scan's table) to glTF's Y up.
  const d = { back: [0, -1, 0], palm: [0, 1, 0], side: [0, 0, 1] }[name];
  camera.position.copy(state.centre).add(new THREE.Vector3(...d).multiplyScalar(state.radius * 4.2));
  camera.up.set(name === 'side' ? 0 : 0, name === 'side' ? 1 : 0, name === 'side' ? 0 : -1);
  controls.target.copy(state.centre);
  controls.update();
  requestRender();
}

function applyJoints(joints) {
  for (const [name, n] of Object.entries(joints)) {
    const b = state.bones[name];
    if (!b) continue;
    b.position.set(...n.t);
    b.quaternion.set(...n.q);
  }
  requestRender();
}

// The solver's angles on the sliders, except those the user holds (inputs, and sliders moved):
// a reply to an older request must not undo a newer move.
function showValues(angles, all = false) {
  for (const d of state.dofs) {
    if (state.mode[d.name] === 'torque') continue;  // the slider is the torque, not the angle
    if (!all && (state.mode[d.name] === 'input' || state.touched?.has(d.name))) continue;
    state.values[d.name] = angles[d.name];
    const row = document.getElementById('dof-' + d.name);
    row.querySelector('input').value = angles[d.name];
    row.querySelector('output').value = angles[d.name].toFixed(1);
  }
}

// One solve at a time; while one runs, the latest request waits (sliders move faster than 30 ms).
async function solve() {
  if (state.busy) { state.pending = true; return; }
  state.busy = true;
  const inputs = {};
  const anyInput = state.dofs.some(d => state.mode[d.name] === 'input');
  for (const d of state.dofs)
    if (!anyInput || state.mode[d.name] === 'input' || state.touched?.has(d.name)) inputs[d.name] = state.values[d.name];
  const torques = {};
  for (const d of state.dofs)
    if (state.mode[d.name] === 'torque') { torques[d.name] = state.values[d.name]; delete inputs[d.name]; }
  const t0 = performance.now();
  try {
    const local = state.solveIn === 'page' ? state.local[state.parameterSet] : null;
    if (local) {  // the linear model, solved here
      const r = local.solve(inputs, torques);
      state.poser.apply(r.angles);
      requestRender();
      showValues(r.angles);
      state.lastEnergy = r.energy;
    } else {
      const r = await api('/api/solve', { inputs, torques, parameter_set: state.parameterSet });
      applyJoints(r.joints);
      showValues(r.angles);
      state.lastEnergy = r.energy;
    }
    state.lastSolvedIn = local ? 'page' : 'server';
    state.lastSolveMs = performance.now() - t0;
    state.answered = true;
    status.textContent = `solved in the ${state.lastSolvedIn} in ${state.lastSolveMs.toFixed(2)} ms, potential ${state.lastEnergy.toFixed(2)}`;
  } catch (e) {
    status.textContent = 'error: ' + e.message;
  }
  state.busy = false;
  if (state.pending) { state.pending = false; solve(); }
}

function buildSliders() {
  const side = document.getElementById('side');
  const groups = {};
  for (const d of state.dofs) {
    const g = d.name.split('.')[0];
    if (!groups[g]) {
      const fs = document.createElement('fieldset');
      const lg = document.createElement('legend');
      lg.textContent = g;
      fs.appendChild(lg);
      side.appendChild(fs);
      groups[g] = fs;
    }
    const row = document.createElement('div');
    row.className = 'dof';
    row.id = 'dof-' + d.name;
    const id = 'slider-' + d.name.replace(/\./g, '-');
    row.innerHTML = `<label for="${id}" title="${d.name}${d.alias ? ' (' + d.alias + ')' : ''}">${d.name.split('.').slice(1).join('.')}${d.alias ? ' ' + d.alias : ''}</label>` +
      `<input type="range" id="${id}" min="${d.min}" max="${d.max}" step="0.5" value="${d.relaxed}" aria-label="${d.name} (${d.unit})">` +
      `<output for="${id}">${d.relaxed.toFixed(1)}</output>` +
      `<select aria-label="${d.name} mode"><option value="free">free</option><option value="input">input</option><option value="torque">torque</option></select>`;
    const slider = row.querySelector('input'), mode = row.querySelector('select');
    slider.addEventListener('input', () => {
      state.values[d.name] = parseFloat(slider.value);
      row.querySelector('output').value = parseFloat(slider.value).toFixed(1);
      (state.touched ??= new Set()).add(d.name);
      if (state.redrawStart === null) state.redrawStart = performance.now();
      solve();
    });
    mode.addEventListener('change', () => {
      state.mode[d.name] = mode.value;
      row.classList.toggle('input', mode.value !== 'free');
      if (mode.value === 'torque') {  // a torque slider starts at no torque
        state.values[d.name] = 0;
        slider.value = 0;
        row.querySelector('output').value = '0.0';
      }
      solve();
    });
    groups[g].appendChild(row);
    state.mode[d.name] = 'free';
  }
}

// --- keys: capture, edit, play, export, import (POST /api/animate) ---
state.keys = [];
state.played = 0;
function currentKeyAngles() {
  const inputsOnly = document.getElementById('inputs-only').checked;
  const angles = {};
  for (const d of state.dofs)
    if (!inputsOnly || state.mode[d.name] === 'input') angles[d.name] = state.values[d.name];
  return angles;
}
function renderKeys() {
  const list = document.getElementById('key-list');
  list.innerHTML = '';
  state.keys.forEach((k, i) => {
    const li = document.createElement('li');
    const n = Object.keys(k.angles).length;
    li.innerHTML = `<label>at <input type="number" min="0" max="3600" step="0.1" value="${k.time}" aria-label="key ${i + 1} time (s)"> s</label>` +
      ` ${n} DOF${n === 1 ? '' : 's'} <button aria-label="move key ${i + 1} earlier">↑</button><button aria-label="move key ${i + 1} later">↓</button>` +
      `<button aria-label="delete key ${i + 1}">✕</button>`;
    const [time] = li.querySelectorAll('input');
    const [up, down, del] = li.querySelectorAll('button');
    time.onchange = () => { k.time = parseFloat(time.value); };
    // Moving a key swaps its posture with its neighbour's; the times stay in order.
    const swap = j => { if (j < 0 || j >= state.keys.length) return; [state.keys[i].angles, state.keys[j].angles] = [state.keys[j].angles, state.keys[i].angles]; renderKeys(); };
    up.onclick = () => swap(i - 1);
    down.onclick = () => swap(i + 1);
    del.onclick = () => { state.keys.splice(i, 1); renderKeys(); };
    list.appendChild(li);
  });
}
function addKey() {
  const step = parseFloat(document.getElementById('key-step').value) || 1;
  const time = state.keys.length ? state.keys[state.keys.length - 1].time + step : 0;
  state.keys.push({ time: Math.round(time * 1000) / 1000, angles: currentKeyAngles() });
  renderKeys();
  status.textContent = `${state.keys.length} key(s)`;
}
function animationRequest(format) {
  return { keys: state.keys.map(k => ({ time: k.time, angles: k.angles })), fps: parseFloat(document.getElementById('fps').value) || 30,
           inputs_only: document.getElementById('inputs-only').checked, format, parameter_set: state.parameterSet };
}
async function play() {
  if (state.keys.length < 2) { status.textContent = 'add at least two keys to play'; return; }
  let r;
  try { r = await api('/api/animate', animationRequest('frames')); } catch (e) { status.textContent = 'error: ' + e.message; return; }
  state.playing = true;
  state.played = 0;
  const start = performance.now(), last = r.times[r.times.length - 1];
  await new Promise(done => {
    const step = () => {
      const t = Math.min((performance.now() - start) / 1000, last);
      let f = 0;
      while (f + 1 < r.times.length && r.times[f + 1] <= t) ++f;
      r.frames[f].joints.forEach((n, j) => {
        const b = state.bones[r.joint_names[j]];
        if (b) { b.position.set(n[0], n[1], n[2]); b.quaternion.set(n[3], n[4], n[5], n[6]); }
      });
      state.played++;
      status.textContent = `playing ${t.toFixed(2)} / ${last.toFixed(2)} s`;
      requestRender();
      if (t < last) requestAnimationFrame(step); else done();
    };
    requestAnimationFrame(step);
  });
  const angles = {};
  r.dofs.forEach((name, k) => { angles[name] = r.frames[r.frames.length - 1].angles[k]; });
  showValues(angles, true);
  state.playing = false;
  status.textContent = `played ${r.frames.length} frames over ${last.toFixed(2)} s` + (r.clamped ? ` (${r.clamped} values put on their limits)` : '');
}
async function exportAnimation(format) {
  if (state.keys.length < 2) { status.textContent = 'add at least two keys to export'; return; }
  const r = await fetch('/api/animate', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(animationRequest(format)) });
  if (!r.ok) { status.textContent = 'error: ' + (await r.json()).error; return; }
  const url = URL.createObjectURL(await r.blob());
  const a = document.createElement('a');
  a.href = url;
  a.download = format === 'glb' ? 'animation.glb' : 'animation.csv';
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
  status.textContent = `exported ${a.download}`;
}
// Keys from a CSV: a header of DOF names or aliases and an optional "time" column; empty cells
// are not given (the format `handskin animate --keys` reads).
function importKeys(text) {
  const lines = text.replace(/^\uFEFF/, '').split(/\r?\n/).filter(l => l.trim() !== '');
  if (lines.length < 3) throw new Error('a keys CSV needs a header and at least two rows');
  const byName = {};
  for (const d of state.dofs) { byName[d.name.toLowerCase()] = d.name; if (d.alias) byName[d.alias.toLowerCase()] = d.name; }
  const head = lines[0].split(',').map(c => c.trim());
  const cols = head.map(h => (h.toLowerCase() === 'time' ? 'time' : byName[h.toLowerCase()]));
  cols.forEach((c, i) => { if (!c) throw new Error(`unknown DOF '${head[i]}' in the header`); });
  state.keys = lines.slice(1).map((l, r) => {
    const cells = l.split(',').map(c => c.trim());
    if (cells.length !== cols.length) throw new Error(`line ${r + 2}: ${cells.length} cells, the header has ${cols.length}`);
    const k = { time: r, angles: {} };
    cells.forEach((c, i) => {
      if (c === '') return;
      const v = Number(c);
      if (!Number.isFinite(v)) throw new Error(`line ${r + 2}: '${c}' is not a number`);
      if (cols[i] === 'time') k.time = v; else k.angles[cols[i]] = v;
    });
    return k;
  });
  renderKeys();
  status.textContent = `imported ${state.keys.length} keys`;
}
Object.assign(state, { addKey, play, exportAnimation, importKeys });

// --- the piano: a key under each fingertip; a computer key presses it: an input to the
// finger's two flexion DOFs, the solver moves the whole hand, the bones ease to the answer ---
const PIANO = [
  { key: 'a', finger: 'little', dofs: { 'little.mcp.flex': 45, 'little.pip.flex': 50 }, tip: 'pinky-finger-tip', note: 261.63 },
  { key: 's', finger: 'ring', dofs: { 'ring.mcp.flex': 45, 'ring.pip.flex': 50 }, tip: 'ring-finger-tip', note: 293.66 },
  { key: 'd', finger: 'middle', dofs: { 'middle.mcp.flex': 45, 'middle.pip.flex': 50 }, tip: 'middle-finger-tip', note: 329.63 },
  { key: 'f', finger: 'index', dofs: { 'index.mcp.flex': 45, 'index.pip.flex': 50 }, tip: 'index-finger-tip', note: 349.23 },
  { key: ' ', finger: 'thumb', dofs: { 'thumb.mcp.flex': 35, 'thumb.ip.flex': 40 }, tip: 'thumb-tip', note: 392.0 },
];
const piano = { on: false, ready: false, pressed: new Set(), meshes: [], group: null, target: null, audio: null, presses: 0, palmar: new THREE.Vector3(0, -1, 0) };
state.piano = piano;
// The keyboard sits under the fingertips of the relaxed posture, on the palm's side: the way a
// fingertip moves when its finger flexes (asked of the solver, so left hands work alike).
async function buildPiano() {
  const tipsAt = async inputs => {
    const r = await api('/api/solve', { inputs });
    applyJoints(r.joints);
    scene.updateMatrixWorld(true);
    const out = {};
    for (const k of PIANO) out[k.tip] = state.bones[k.tip].getWorldPosition(new THREE.Vector3());
    return out;
  };
  const flexed = await tipsAt({ 'index.mcp.flex': 60 });
  const relaxed = await tipsAt({});
  // Along the finger (MCP to tip), and the tip's motion square to it: toward the palm.
  const mcp = state.bones['index-finger-phalanx-proximal'].getWorldPosition(new THREE.Vector3());
  const along = relaxed['index-finger-tip'].clone().sub(mcp).normalize();
  const palmar = flexed['index-finger-tip'].clone().sub(relaxed['index-finger-tip']);
  palmar.addScaledVector(along, -palmar.dot(along)).normalize();
  piano.palmar = palmar;
  piano.group = new THREE.Group();
  for (const k of PIANO) {
    const box = new THREE.Mesh(new THREE.BoxGeometry(0.018, 0.018, 0.018),
                               new THREE.MeshStandardMaterial({ color: 0xfafafa, roughness: 0.5 }));
    box.position.copy(relaxed[k.tip]).addScaledVector(palmar, 0.022);
    box.userData.rest = box.position.clone();
    piano.group.add(box);
    piano.meshes.push(box);
  }
  scene.add(piano.group);
  piano.target = null;
  state.touched = new Set();
}
function pianoSolve() {
  const inputs = {};
  for (const d of state.dofs) if (state.mode[d.name] === 'input') inputs[d.name] = state.values[d.name];
  for (const i of piano.pressed) Object.assign(inputs, PIANO[i].dofs);
  api('/api/solve', { inputs, parameter_set: state.parameterSet }).then(r => { piano.target = r.joints; showValues(r.angles, true); requestRender(); })
    .catch(e => { status.textContent = 'error: ' + e.message; });
}
function sound(freq) {
  try {
    piano.audio ??= new AudioContext();
    const ctx = piano.audio, o = ctx.createOscillator(), g = ctx.createGain();
    o.type = 'triangle';
    o.frequency.value = freq;
    g.gain.setValueAtTime(0.2, ctx.currentTime);
    g.gain.exponentialRampToValueAtTime(0.001, ctx.currentTime + 0.8);
    o.connect(g).connect(ctx.destination);
    o.start();
    o.stop(ctx.currentTime + 0.8);
  } catch (e) { /* no audio device: the piano still moves */ }
}
function pianoKey(ev, down) {
  if (!piano.on || ev.target.tagName === 'INPUT' || ev.target.tagName === 'SELECT') return;
  const i = PIANO.findIndex(k => k.key === ev.key.toLowerCase());
  if (i < 0) return;
  ev.preventDefault();
  if (down === piano.pressed.has(i)) return;  // key repeat
  if (down) { piano.pressed.add(i); piano.presses++; sound(PIANO[i].note); } else piano.pressed.delete(i);
  const m = piano.meshes[i];
  m.position.copy(m.userData.rest).addScaledVector(piano.palmar, down ? 0.005 : 0);
  m.material.color.set(down ? 0xc7d7f5 : 0xfafafa);
  requestRender();
  pianoSolve();
}
// Softly: each frame the bones go a fifth of the way to the solver's answer. True while they
// are still on their way (another frame is wanted).
const easeT = new THREE.Vector3(), easeQ = new THREE.Quaternion();
function easeBones() {
  if (!piano.target) return false;
  let moving = false;
  for (const [name, n] of Object.entries(piano.target)) {
    const b = state.bones[name];
    if (!b) continue;
    easeT.set(...n.t);
    easeQ.set(...n.q);
    moving ||= b.position.distanceToSquared(easeT) > 1e-14 || 1 - Math.abs(b.quaternion.dot(easeQ)) > 1e-12;
    b.position.lerp(easeT, 0.2);
    b.quaternion.slerp(easeQ, 0.2);
  }
  return moving;
}
async function togglePiano() {
  piano.on = !piano.on;
  if (piano.on && !piano.group) await buildPiano();
  piano.group.visible = piano.on;
  piano.pressed.clear();
  piano.target = null;
  if (piano.on) {
    pianoSolve();
    // The hand over its keyboard: seen from the side, a little from above, the palm down.
    const side = new THREE.Vector3(0, 0, 1);
    side.addScaledVector(piano.palmar, -side.dot(piano.palmar)).normalize();
    camera.position.copy(state.centre).addScaledVector(side, state.radius * 4).addScaledVector(piano.palmar, -state.radius * 1.6);
    camera.up.copy(piano.palmar).negate();
    controls.target.copy(state.centre);
    controls.update();
  }
  const b = document.getElementById('piano-button');
  b.setAttribute('aria-pressed', String(piano.on));
  piano.ready = piano.on;
  requestRender();
  status.textContent = piano.on ? 'piano: A S D F Space press the little, ring, middle, index finger and the thumb' : 'piano off';
}
window.addEventListener('keydown', ev => pianoKey(ev, true));
window.addEventListener('keyup', ev => pianoKey(ev, false));

async function main() {
  resize();
  const info = await api('/api/dofs');
  state.dofs = info.dofs;
  for (const d of state.dofs) state.values[d.name] = d.relaxed;
  state.parameterSet = info.parameter_sets[0];
  const sets = document.getElementById('parameter-set');
  for (const name of info.parameter_sets) {
    const o = document.createElement('option');
    o.value = name;
    o.textContent = name === 'model' ? `skin.glb (${info.parameter_set})` : name;
    sets.appendChild(o);
  }
  sets.onchange = () => { state.parameterSet = sets.value; solve(); };
  buildSliders();
  const gltf = await new GLTFLoader().loadAsync('/model.glb');
  scene.add(gltf.scene);
  gltf.scene.traverse(o => { if (o.isBone) state.bones[o.name] = o; });
  // The linear parameter sets, solved in the page; the others go to the server.
  const sys = await api('/api/system');
  const names = state.dofs.map(d => d.name);
  for (const [name, set] of Object.entries(sys.sets)) if (set.linear) state.local[name] = new LinearPostureSolver(set, names);
  state.poser = new JointPoser(sys.joints, state.bones, names);
  const solveIn = document.getElementById('solve-in');
  solveIn.value = state.solveIn;
  solveIn.onchange = () => { state.solveIn = solveIn.value; };
  controls.addEventListener('change', requestRender);
  const box = new THREE.Box3().setFromObject(gltf.scene);
  box.getCenter(state.centre);
  state.radius = box.getSize(new THREE.Vector3()).length() / 2;
  setView('back');
  for (const v of ['back', 'palm', 'side']) document.getElementById('v-' + v).onclick = () => setView(v);
  document.getElementById('relaxed').onclick = () => { state.touched = new Set(); for (const d of state.dofs) { state.mode[d.name] = 'free'; document.querySelector(`#dof-${CSS.escape(d.name)} select`).value = 'free'; document.getElementById('dof-' + d.name).classList.remove('input'); } api('/api/solve', { inputs: {} }).then(r => { applyJoints(r.joints); showValues(r.angles, true); }); };
  document.getElementById('scan').onclick = () => { const inputs = {}; for (const d of state.dofs) inputs[d.name] = 0; state.touched = new Set(state.dofs.map(d => d.name)); api('/api/solve', { inputs }).then(r => { applyJoints(r.joints); showValues(r.angles, true); }); };
  const help = document.getElementById('help'), hb = document.getElementById('help-button');
  hb.onclick = () => { const open = help.style.display !== 'block'; help.style.display = open ? 'block' : 'none'; hb.setAttribute('aria-expanded', String(open)); };
  document.getElementById('piano-button').onclick = togglePiano;
  document.getElementById('key-add').onclick = addKey;
  document.getElementById('play').onclick = play;
  document.getElementById('export-glb').onclick = () => exportAnimation('glb');
  document.getElementById('export-csv').onclick = () => exportAnimation('csv');
  document.getElementById('import-csv').onchange = async ev => {
    const f = ev.target.files[0];
    if (!f) return;
    try { importKeys(await f.text()); } catch (e) { status.textContent = 'error: ' + e.message; }
  };
  await solve();
  state.ready = true;
  requestRender();
}
main().catch(e => { status.textContent = 'error: ' + e.message; });
