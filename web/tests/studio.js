// End-to-end test of the hand studio in headless Chromium (Debian's chromium, driven by
// playwright-core): `handskin studio` on a skin.glb, the page loads, the L2 (little MCP)
// slider in input mode moves the other fingers through the solver and changes the picture;
// two keys recorded (L2 0° and 80°, inputs only) play back to the second posture and export as
// a glTF animation that the Khronos validator passes (saved as studio_animation.glb); the
// piano's F key bends the index finger (studio_piano.png); the page's own solver gives the
// server's answers, and the slider-to-redraw time is reported both ways.
// Usage: node web/tests/studio.js <handskin> <skin.glb> <artefacts-folder>
const fs = require('fs');
const path = require('path');
const { chromium } = require('playwright-core');
const { startStudio, pixelDifference, solverAgreement, agreementOk } = require('./studio_common.js');

const [bin, glb, art] = process.argv.slice(2);
if (!bin || !glb || !art) {
  console.error('usage: node web/tests/studio.js <handskin> <skin.glb> <artefacts-folder>');
  process.exit(2);
}

(async () => {
  let studio, browser, code = 1;
  try {
    studio = await startStudio(bin, glb);
    browser = await chromium.launch({ executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
                                      args: ['--no-sandbox', '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] });
    const page = await browser.newPage({ viewport: { width: 1100, height: 700 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    await page.goto(studio.url);
    await page.waitForFunction(() => window.studio && window.studio.ready, null, { timeout: 60000 });
    const before = await page.evaluate(() => ({ ...window.studio.values }));
    const shot0 = await page.locator('canvas').screenshot();
    await page.screenshot({ path: path.join(art, 'studio_before.png') });
    // L2 (little MCP flexion) as an input, moved to 80 degrees.
    await page.selectOption('#dof-little\\.mcp\\.flex select', 'input');
    await page.locator('#slider-little-mcp-flex').fill('80');
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex'] - 80) < 1e-6 && !window.studio.busy, null, { timeout: 20000 });
    await page.waitForTimeout(500);
    const after = await page.evaluate(() => ({ ...window.studio.values, solveMs: window.studio.lastSolveMs }));
    const shot1 = await page.locator('canvas').screenshot();
    await page.screenshot({ path: path.join(art, 'studio_L2_input.png') });
    const moved = ['ring.mcp.flex', 'ring.pip.flex', 'middle.mcp.flex'].filter((d) => Math.abs(after[d] - before[d]) > 1);
    const diff = pixelDifference(shot0, shot1);

    // The page's own solver (linear parameter sets) against the server's: the same angles, the
    // same potential and the same joint transforms for the same inputs and torques.
    const agreement = await page.evaluate(solverAgreement);
    const agreeOk = agreementOk(agreement);

    // Slider to redrawn hand, solved in the server and in the page (15 moves each; the page
    // records from the slider's move to the end of the frame that shows the answer).
    const redraw = {};
    for (const where of ['server', 'page']) {
      await page.selectOption('#solve-in', where);
      const ms = [];
      for (let k = 0; k < 15; ++k) {
        const n = await page.evaluate(() => window.studio.redrawMs.length);
        await page.locator('#slider-little-mcp-flex').fill(String(20 + 4 * k));
        await page.waitForFunction(n0 => window.studio.redrawMs.length > n0, n, { timeout: 20000 });
        const r = await page.evaluate(() => ({ ms: window.studio.lastRedrawMs, where: window.studio.lastSolvedIn }));
        if (r.where !== where) throw new Error(`asked to solve in the ${where}, solved in the ${r.where}`);
        ms.push(r.ms);
        await page.waitForTimeout(50);
      }
      ms.sort((a, b) => a - b);
      redraw[where] = { p50_ms: +ms[7].toFixed(1), max_ms: +ms[14].toFixed(1), min_ms: +ms[0].toFixed(1) };
    }
    await page.selectOption('#solve-in', 'page');

    // Keys: L2 back to 0 as the first key, 80 as the second (inputs only: the solver fills in
    // every frame), then play them and export the animation.
    await page.check('#inputs-only');
    await page.locator('#slider-little-mcp-flex').fill('0');
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex']) < 1e-6 && !window.studio.busy, null, { timeout: 20000 });
    await page.click('#key-add');
    await page.locator('#slider-little-mcp-flex').fill('80');
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex'] - 80) < 1e-6 && !window.studio.busy, null, { timeout: 20000 });
    await page.click('#key-add');
    const keys = await page.evaluate(() => window.studio.keys);
    await page.locator('#slider-little-mcp-flex').fill('0');  // away from the last key, so playing shows a change
    await page.waitForFunction(() => !window.studio.busy, null, { timeout: 20000 });
    await page.waitForTimeout(300);
    const shotKey0 = await page.locator('canvas').screenshot();
    await page.click('#play');
    await page.waitForFunction(() => window.studio.played > 0 && !window.studio.playing, null, { timeout: 30000 });
    const played = await page.evaluate(() => ({ frames: window.studio.played, ring: window.studio.values['ring.mcp.flex'],
                                                little: window.studio.values['little.mcp.flex'] }));
    await page.waitForTimeout(300);
    const shotPlayed = await page.locator('canvas').screenshot();
    await page.screenshot({ path: path.join(art, 'studio_played.png') });
    const [download] = await Promise.all([page.waitForEvent('download'), page.click('#export-glb')]);
    const exported = path.join(art, 'studio_animation.glb');
    await download.saveAs(exported);
    const validator = require('gltf-validator');
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(exported)), { maxIssues: 100 });
    const playDiff = pixelDifference(shotKey0, shotPlayed);

    // A torque instead of an angle: the index MCP turns toward it; another parameter set answers differently.
    const beforeTorque = await page.evaluate(() => window.studio.values['index.mcp.flex']);
    await page.selectOption('#dof-index\\.mcp\\.flex select', 'torque');
    await page.locator('#slider-index-mcp-flex').fill('20');
    await page.waitForFunction(() => !window.studio.busy, null, { timeout: 20000 });
    await page.waitForTimeout(300);
    const torque = await page.evaluate(() => ({ torque: window.studio.values['index.mcp.flex'], ring: window.studio.values['ring.mcp.flex'] }));
    const solvedWithTorque = await page.evaluate(async () => (await (await fetch('/api/solve', { method: 'POST',
      body: JSON.stringify({ torques: { 'index.mcp.flex': 20 } }) })).json()).angles['index.mcp.flex']);
    await page.selectOption('#parameter-set', 'thesis');
    await page.waitForFunction(() => !window.studio.busy, null, { timeout: 20000 });
    // The same torques under the thesis's parameters: a different whole-hand answer.
    const thesis = await page.evaluate(async () => {
      const ask = async set => (await (await fetch('/api/solve', { method: 'POST',
        body: JSON.stringify({ torques: { 'index.mcp.flex': 20 }, parameter_set: set }) })).json()).angles;
      const a = await ask('model'), b = await ask('thesis');
      return Object.keys(a).reduce((s, k) => s + Math.abs(a[k] - b[k]), 0);
    });
    await page.selectOption('#dof-index\\.mcp\\.flex select', 'free');
    await page.selectOption('#parameter-set', 'model');
    await page.waitForFunction(() => !window.studio.busy, null, { timeout: 20000 });
    const torqueOk = solvedWithTorque > beforeTorque + 5 && thesis > 1;
    if (!torqueOk) console.error('studio: a torque on the index MCP did not turn it, or the thesis parameters answered the same');

    // The piano: F presses the index finger's key; the index MCP and PIP bend, the picture changes.
    await page.click('#piano-button');
    await page.waitForFunction(() => window.studio.piano.ready, null, { timeout: 20000 });
    await page.waitForTimeout(800);
    const shotPiano0 = await page.locator('canvas').screenshot();
    const indexBefore = await page.evaluate(() => window.studio.values['index.mcp.flex']);
    await page.keyboard.down('f');
    await page.waitForFunction(() => Math.abs(window.studio.values['index.mcp.flex'] - 45) < 1e-6, null, { timeout: 20000 });
    await page.waitForTimeout(800);  // the bones ease to the answer
    const shotPiano1 = await page.locator('canvas').screenshot();
    await page.screenshot({ path: path.join(art, 'studio_piano.png') });
    const pianoState = await page.evaluate(() => ({ presses: window.studio.piano.presses, index_mcp: window.studio.values['index.mcp.flex'],
                                                    index_pip: window.studio.values['index.pip.flex'] }));
    await page.keyboard.up('f');
    const pianoDiff = pixelDifference(shotPiano0, shotPiano1);
    console.log(JSON.stringify({ url: studio.url, moved, ring_mcp: [before['ring.mcp.flex'], after['ring.mcp.flex']],
                                 picture_difference: diff, solve_ms: after.solveMs, keys: keys.length, played,
                                 play_picture_difference: playDiff, exported_bytes: fs.statSync(exported).size,
                                 validator: { errors: report.issues.numErrors, warnings: report.issues.numWarnings },
                                 piano: { ...pianoState, index_mcp_before: indexBefore, picture_difference: pianoDiff },
                                 torque: { index_mcp_before: beforeTorque, index_mcp_with_torque_20: solvedWithTorque,
                                           thesis_differs_by_deg: thesis },
                                 page_solver_agreement: agreement, slider_to_redraw: redraw,
                                 page_errors: errors }));
    let ok = errors.length === 0 && moved.length >= 2 && diff > 0.01;
    if (!ok) console.error('studio: moving L2 in input mode did not move the other fingers or the picture');
    const animated = keys.length === 2 && played.frames > 1 && Math.abs(played.little - 80) < 1e-6 && played.ring > 40 &&
                     playDiff > 0.01 && report.issues.numErrors === 0 && report.issues.numWarnings === 0;
    if (!animated) console.error('studio: two keys did not play to the second posture, or the exported animation is not valid glTF');
    ok = ok && animated;
    const pianoOk = pianoState.presses === 1 && Math.abs(pianoState.index_pip - 50) < 1e-6 && pianoDiff > 0.01;
    if (!pianoOk) console.error('studio: pressing F on the piano did not bend the index finger or change the picture');
    ok = ok && pianoOk && torqueOk && agreeOk;
    code = ok ? 0 : 1;
  } catch (e) {
    console.error('studio: ' + (e.message || e));
  } finally {
    if (browser) await browser.close();
    if (studio) studio.proc.kill();
    process.exit(code);
  }
})();
