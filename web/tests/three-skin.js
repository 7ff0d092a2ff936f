// A real client on skin.glb: three.js's GLTFLoader in headless Chromium (Debian's chromium,
// driven by playwright-core). Serves web/ and the glb on a local port, opens
// web/tests/three-skin.html, checks that the skeleton has the 25 joints and that bending
// one moves the skin, and saves a screenshot.
// Usage: node web/tests/three-skin.js skin.glb screenshot.png
const http = require('http');
const fs = require('fs');
const path = require('path');
const { chromium } = require('playwright-core');

const [glb, shot] = process.argv.slice(2);
if (!glb || !shot) {
  console.error('usage: node web/tests/three-skin.js skin.glb screenshot.png');
  process.exit(2);
}
const root = path.resolve(__dirname, '..');
const types = { '.html': 'text/html', '.js': 'text/javascript', '.glb': 'model/gltf-binary' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  const file = url === '/skin.glb' ? path.resolve(glb) : path.join(root, path.normalize(url));
  if (url !== '/skin.glb' && !file.startsWith(root + path.sep)) { res.writeHead(403); res.end(); return; }
  fs.readFile(file, (err, data) => {
    if (err) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    res.end(data);
  });
});

server.listen(0, '127.0.0.1', async () => {
  const port = server.address().port;
  let browser, code = 1;
  try {
    browser = await chromium.launch({ executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
                                      args: ['--no-sandbox', '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] });
    const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    await page.goto(`http://127.0.0.1:${port}/tests/three-skin.html?glb=/skin.glb`);
    await page.waitForFunction(() => window.result !== undefined, null, { timeout: 60000 });
    const r = await page.evaluate(() => window.result);
    await page.screenshot({ path: shot });
    console.log(JSON.stringify({ ...r, names: undefined, page_errors: errors }));
    const ok = !r.error && errors.length === 0 && r.bones === 25 && r.names.includes('index-finger-phalanx-intermediate') &&
               r.vertices > 1000 && r.moved > 50 && r.most_moved_m > 0.01;
    if (!ok) console.error('three-skin: the glb did not load, or bending a joint did not move the skin');
    code = ok ? 0 : 1;
  } catch (e) {
    console.error('three-skin: ' + (e.message || e));
  } finally {
    if (browser) await browser.close();
    server.close();
    process.exit(code);
  }
});
