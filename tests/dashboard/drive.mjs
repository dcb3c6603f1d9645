// The dashboard in a real browser (Debian's headless Chromium, driven by playwright-core): log in, see the
// capabilities, drive with the pad and see the sim drive's timeline move, press STOP and see the latch, clear it, and
// lose the connection while holding the pad and see the motors stop, and stop one node of the swarm table (a second
// robot, NODE at NODE_URL) and see that node latched and this one not. A screenshot of each step goes to SHOTS.
// Usage: node drive.mjs BASE_URL TOKEN SHOTS_DIR NODE NODE_URL   (exit 0: every step held; else the failed step on stderr)
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';

const [base, token, shots, node, nodeUrl] = process.argv.slice(2);
mkdirSync(shots, { recursive: true });
const auth = { Authorization: `Bearer ${token}` };

async function robot(path, init = {}, at = base) {
  const response = await fetch(at + path, { ...init, headers: { ...auth, ...(init.headers || {}) } });
  return response.json();
}
// The sim drive's timeline: every wheel-speed change it was told, oldest first.
async function timeline() {
  const doc = await robot('/api/drivers/drive0');
  return doc.status.timeline;
}
const moving = (events) => events.filter((e) => e.left !== 0 || e.right !== 0).length;
async function until(what, condition, timeoutMs = 5000) {
  const deadline = Date.now() + timeoutMs;
  for (;;) {
    const value = await condition();
    if (value) return value;
    if (Date.now() > deadline) throw new Error(`timed out waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 20));  // polls the robot over HTTP: no event to wait on from here
  }
}
function check(what, ok, detail = '') {
  if (!ok) throw new Error(`${what} ${detail}`);
  console.log(`ok - ${what} ${detail}`);
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync'],
});
let failed = false;
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 900 } });
  const page = await context.newPage();
  page.on('pageerror', (e) => { console.error(`page error: ${e.message}`); failed = true; });

  // 1. Log in.
  await page.goto(base + '/');
  await page.screenshot({ path: `${shots}/1-login.png` });
  await page.fill('#token', 'not-the-token');
  await page.click('#login-form button');
  await page.waitForFunction(() => document.getElementById('login-error').textContent.length > 0);
  check('a wrong token is refused on the login page', await page.isHidden('#app'));
  await page.fill('#token', token);
  await page.click('#login-form button');
  await page.waitForSelector('#app:not([hidden])');

  // 2. The robot's capabilities, and the live link.
  await page.waitForFunction(() => document.querySelectorAll('#capabilities li').length > 0);
  const caps = await page.$$eval('#capabilities li', (items) => items.map((li) => li.dataset.name));
  check('capabilities shown', caps.includes('teleop') && caps.includes('nav'), caps.join(','));
  await page.waitForFunction(() => document.getElementById('link').textContent === 'live', null, { timeout: 5000 });
  check('live telemetry link', true);
  await page.screenshot({ path: `${shots}/2-dashboard.png`, fullPage: true });

  // 3. Drive with the pad: hold forward, the timeline moves; release, it stops.
  const before = moving(await timeline());
  const forward = await page.$('[data-drive=forward]');
  const box = await forward.boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await until('the sim drive to move', async () => moving(await timeline()) > before);
  await page.screenshot({ path: `${shots}/3-driving.png` });
  await page.mouse.up();
  await until('the sim drive to stop after release', async () => {
    const events = await timeline();
    const last = events[events.length - 1];
    return last.left === 0 && last.right === 0;
  }, 2000);
  check('pad drives and stops on release', true, `${moving(await timeline()) - before} motion events`);

  // 4. STOP: the page shows the latch (pushed over the WebSocket), the robot is latched.
  const pressed = Date.now();
  await page.click('#estop');
  await page.waitForFunction(() => document.getElementById('state').textContent === 'E-STOPPED', null, { timeout: 2000 });
  const shownMs = Date.now() - pressed;
  const estop = await robot('/api/estop');
  check('STOP latches the robot and the page shows it', estop.latched === true || estop.estopped === true, `in ${shownMs} ms`);
  await page.screenshot({ path: `${shots}/4-estopped.png` });
  await page.keyboard.press('Escape');  // the keyboard stop works while latched too (idempotent)

  // 5. Clear (owner).
  await page.click('#clear');
  await page.waitForFunction(() => document.getElementById('state').textContent !== 'E-STOPPED', null, { timeout: 2000 });
  check('clear shown to the owner and it clears', true);

  // 6. The swarm table: the other robot is listed with its state; its Stop latches that robot only.
  const row = `#swarm tr[data-node="${node}"]`;
  await page.waitForSelector(`${row}[data-state=ok]`, { timeout: 5000 });
  check('the swarm table lists the node, reachable', true, node);
  await page.click(`${row} .node-stop`);
  await until(`${node} to latch`, async () => (await robot('/api/estop', {}, nodeUrl)).estopped === true, 3000);
  await page.waitForSelector(`${row}[data-state=estopped]`, { timeout: 5000 });
  const local = await robot('/api/estop');
  check('per-node stop latches that node only', local.estopped === false, `${node} latched, this robot not`);
  await page.screenshot({ path: `${shots}/7-swarm.png`, fullPage: true });

  // 7. Hold the pad, then lose the connection: the motors stop by themselves (each move is a 300 ms lease).
  const beforeHold = moving(await timeline());
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await until('the sim drive to move again', async () => moving(await timeline()) > beforeHold);
  await context.setOffline(true);
  const lost = Date.now();
  await until('the motors to stop after the link was lost', async () => {
    const events = await timeline();
    const last = events[events.length - 1];
    return last.left === 0 && last.right === 0;
  }, 3000);
  check('link lost while holding: the motors stop', true, `within ${Date.now() - lost} ms`);
  await page.screenshot({ path: `${shots}/5-link-lost.png` });
  await page.mouse.up();
  await context.setOffline(false);

  // 8. A phone-sized view.
  const phone = await browser.newContext({ viewport: { width: 390, height: 844 }, isMobile: true, hasTouch: true });
  const small = await phone.newPage();
  await small.goto(base + '/');
  await small.fill('#token', token);
  await small.click('#login-form button');
  await small.waitForSelector('#app:not([hidden])');
  const stopBox = await (await small.$('#estop')).boundingBox();
  check('the STOP button is within the phone screen', stopBox.x >= 0 && stopBox.x + stopBox.width <= 390);
  await small.screenshot({ path: `${shots}/6-phone.png` });
} catch (e) {
  console.error(`FAILED: ${e.message}`);
  failed = true;
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
