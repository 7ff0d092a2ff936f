// End-to-end test of the hand studio in Firefox (Debian's firefox-esr, driven by npm
// puppeteer-core over WebDriver BiDi; run under Xvfb by scripts/check_studio.sh, as headless
// Firefox has no WebGL on a machine without a GPU): the page loads, its own solver gives the
// server's answers, the L2 slider in input mode moves the other fingers and the picture,
// two keys play, the piano's F key bends the index finger, the keyboard reaches the controls.
// Screenshots: <artefacts>/studio_firefox_*.png.
// Usage: node web/tests/studio_firefox.js <handskin> <skin.glb> <artefacts-folder>
const fs = require('fs');
const path = require('path');
const puppeteer = require('puppeteer-core');
const { startStudio, pixelDifference, solverAgreement, agreementOk } = require('./studio_common.js');

const [bin, glb, art] = process.argv.slice(2);
if (!bin || !glb || !art) {
  console.error('usage: node web/tests/studio_firefox.js <handskin> <skin.glb> <artefacts-folder>');
  process.exit(2);
}

// A range slider moved as a user's drag ends: its value, then an input event.
async function setSlider(page, id, value) {
  await page.$eval(id, (el, v) => { el.value = v; el.dispatchEvent(new Event('input', { bubbles: true })); }, String(value));
}
async function setSelect(page, selector, value) {
  await page.$eval(selector, (el, v) => { el.value = v; el.dispatchEvent(new Event('change', { bubbles: true })); }, value);
}
const canvasShot = async page => Buffer.from(await (await page.$('canvas')).screenshot());
const sleep = ms => new Promise(r => setTimeout(r, ms));

(async () => {
  let studio, browser, code = 1;
  try {
    studio = await startStudio(bin, glb);
    browser = await puppeteer.launch({ browser: 'firefox', executablePath: process.env.FIREFOX || '/usr/bin/firefox-esr',
                                       headless: false, protocol: 'webDriverBiDi', defaultViewport: { width: 1100, height: 700 } });
    const page = await browser.newPage();
    const errors = [];
    page.on('pageerror', e => errors.push(String(e)));
    await page.goto(studio.url);
    await page.waitForFunction(() => window.studio && window.studio.ready, { timeout: 60000 });
    const info = await page.evaluate(() => ({ agent: navigator.userAgent, gl: (() => {
      const g = document.querySelector('canvas').getContext('webgl2');
      return g ? g.getParameter(g.RENDERER) : null;
    })() }));
    const before = await page.evaluate(() => ({ ...window.studio.values }));
    const shot0 = await canvasShot(page);

    const agreement = await page.evaluate(solverAgreement);
    const agreeOk = agreementOk(agreement);

    // L2 (little MCP) as an input, moved to 80°, solved in the page; then timed moves.
    await setSelect(page, '#dof-little\\.mcp\\.flex select', 'input');
    await setSlider(page, '#slider-little-mcp-flex', 80);
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex'] - 80) < 1e-6 && !window.studio.busy &&
                                     window.studio.redrawStart === null, { timeout: 20000 });
    await sleep(300);
    const after = await page.evaluate(() => ({ ...window.studio.values }));
    const shot1 = await canvasShot(page);
    await page.screenshot({ path: path.join(art, 'studio_firefox_L2_input.png') });
    const moved = ['ring.mcp.flex', 'ring.pip.flex', 'middle.mcp.flex'].filter(d => Math.abs(after[d] - before[d]) > 1);
    const diff = pixelDifference(shot0, shot1);
    const ms = [];
    for (let k = 0; k < 11; ++k) {
      const n = await page.evaluate(() => window.studio.redrawMs.length);
      await setSlider(page, '#slider-little-mcp-flex', 20 + 5 * k);
      await page.waitForFunction(n0 => window.studio.redrawMs.length > n0, { timeout: 20000 }, n);
      ms.push(await page.evaluate(() => window.studio.lastRedrawMs));
      await sleep(50);
    }
    ms.sort((a, b) => a - b);
    const redraw = { p50_ms: +ms[5].toFixed(1), min_ms: +ms[0].toFixed(1), max_ms: +ms[10].toFixed(1) };

    // Two keys (inputs only) played back to the second posture.
    await page.click('#inputs-only');
    await setSlider(page, '#slider-little-mcp-flex', 0);
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex']) < 1e-6 && !window.studio.busy, { timeout: 20000 });
    await page.click('#key-add');
    await setSlider(page, '#slider-little-mcp-flex', 80);
    await page.waitForFunction(() => Math.abs(window.studio.values['little.mcp.flex'] - 80) < 1e-6 && !window.studio.busy, { timeout: 20000 });
    await page.click('#key-add');
    await setSlider(page, '#slider-little-mcp-flex', 0);
    await page.waitForFunction(() => !window.studio.busy, { timeout: 20000 });
    await page.click('#play');
    await page.waitForFunction(() => window.studio.played > 0 && !window.studio.playing, { timeout: 30000 });
    const played = await page.evaluate(() => ({ frames: window.studio.played, keys: window.studio.keys.length,
                                                little: window.studio.values['little.mcp.flex'], ring: window.studio.values['ring.mcp.flex'] }));

    // The piano: F bends the index finger; the bones ease there.
    await page.click('#piano-button');
    await page.waitForFunction(() => window.studio.piano.ready, { timeout: 20000 });
    await sleep(800);
    const shotPiano0 = await canvasShot(page);
    await page.keyboard.down('f');
    await page.waitForFunction(() => Math.abs(window.studio.values['index.mcp.flex'] - 45) < 1e-6, { timeout: 20000 });
    await sleep(800);
    const shotPiano1 = await canvasShot(page);
    await page.screenshot({ path: path.join(art, 'studio_firefox_piano.png') });
    const piano = await page.evaluate(() => ({ presses: window.studio.piano.presses, index_pip: window.studio.values['index.pip.flex'] }));
    await page.keyboard.up('f');
    const pianoDiff = pixelDifference(shotPiano0, shotPiano1);

    // The keyboard reaches the controls: Tab from the page's start lands on a labelled button.
    await page.$eval('body', b => b.focus());
    await page.keyboard.press('Tab');
    const focused = await page.evaluate(() => ({ tag: document.activeElement.tagName, text: document.activeElement.textContent.trim() }));

    console.log(JSON.stringify({ browser: await browser.version(), agent: info.agent, webgl: info.gl, moved,
                                 picture_difference: diff, slider_to_redraw_page: redraw, page_solver_agreement: agreement,
                                 played, piano: { ...piano, picture_difference: pianoDiff }, focused, page_errors: errors }));
    const checks = {
      'no page error': errors.length === 0,
      "the page's solver gives the server's answers": agreeOk,
      'L2 as an input moves the other fingers and the picture': moved.length >= 2 && diff > 0.01,
      'two keys play to the second posture': played.keys === 2 && played.frames > 1 && Math.abs(played.little - 80) < 1e-6 && played.ring > 40,
      'the piano bends the index finger': piano.presses === 1 && Math.abs(piano.index_pip - 50) < 1e-6 && pianoDiff > 0.01,
      'Tab reaches a button': focused.tag === 'BUTTON' && focused.text.length > 0,
    };
    for (const [what, ok] of Object.entries(checks)) if (!ok) console.error('studio in Firefox: failed: ' + what);
    code = Object.values(checks).every(Boolean) ? 0 : 1;
  } catch (e) {
    console.error('studio in Firefox: ' + (e.message || e));
  } finally {
    if (browser) await browser.close();
    if (studio) studio.proc.kill();
    process.exit(code);
  }
})();
