// Shared by the studio's end-to-end tests in Chromium (studio.js, playwright-core) and Firefox
// (studio_firefox.js, puppeteer-core over WebDriver BiDi).
const { spawn } = require('child_process');

// `handskin studio` on a free port; resolves with the process and the address it prints.
function startStudio(bin, glb) {
  return new Promise((resolve, reject) => {
    const p = spawn(bin, ['-q', 'studio', '--skin', glb, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
    let out = '';
    p.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/[0-9.]+:\d+\//);
      if (m) resolve({ proc: p, url: m[0] });
    });
    p.on('exit', (code) => reject(new Error('studio exited with ' + code)));
  });
}

function pixelDifference(a, b) {
  // Both PNG buffers of the same size: the share of differing bytes is enough to see a change.
  let diff = 0;
  const n = Math.min(a.length, b.length);
  for (let i = 0; i < n; ++i) diff += a[i] !== b[i];
  return diff / n + Math.abs(a.length - b.length) / Math.max(a.length, b.length);
}

// Runs in the page: the page's own solver (linear parameter sets) against the server's, for
// the same inputs and torques: the largest differences in angle, potential and joint transform.
async function solverAgreement() {
  const s = window.studio;
  let angle = 0, energy = 0, rotation = 0, translation = 0, cases = 0;
  const asks = [{ inputs: {} }, { inputs: { 'little.mcp.flex': 80 } }, { inputs: { 'index.pip.flex': 90, 'thumb.cmc.abd': 40 } },
                { inputs: { 'ring.mcp.flex': -15, 'middle.dip.flex': 70 } }, { inputs: {}, torques: { 'index.mcp.flex': 20 } },
                { inputs: { 'wrist.rx': 30, 'wrist.tz': 12 } }];
  for (const set of Object.keys(s.local))
    for (const ask of asks) {
      const r = await (await fetch('/api/solve', { method: 'POST', body: JSON.stringify({ ...ask, parameter_set: set }) })).json();
      const l = s.local[set].solve(ask.inputs, ask.torques || {});
      for (const k of Object.keys(r.angles)) angle = Math.max(angle, Math.abs(r.angles[k] - l.angles[k]));
      energy = Math.max(energy, Math.abs(r.energy - l.energy));
      s.poser.apply(l.angles);
      for (const [name, n] of Object.entries(r.joints)) {
        const b = s.bones[name];
        const dot = Math.abs(b.quaternion.x * n.q[0] + b.quaternion.y * n.q[1] + b.quaternion.z * n.q[2] + b.quaternion.w * n.q[3]);
        rotation = Math.max(rotation, 1 - dot);
        translation = Math.max(translation, Math.hypot(b.position.x - n.t[0], b.position.y - n.t[1], b.position.z - n.t[2]));
      }
      ++cases;
    }
  return { sets: Object.keys(s.local), cases, max_angle_deg: angle, max_energy: energy, max_rotation_1_minus_dot: rotation,
           max_translation_m: translation };
}

function agreementOk(a) {
  const ok = a.sets.length >= 2 && a.cases >= 12 && a.max_angle_deg < 1e-6 && a.max_energy < 1e-6 &&
             a.max_rotation_1_minus_dot < 1e-9 && a.max_translation_m < 1e-9;
  if (!ok) console.error("studio: the page's solver or joints differ from the server's: " + JSON.stringify(a));
  return ok;
}

module.exports = { startStudio, pixelDifference, solverAgreement, agreementOk };
