// Issue 28 #2 in a real browser (Debian's headless Chromium, driven by playwright-core): a page tries what a hostile page
// of another origin tried against a robot in auth mode open - clear the e-stop and drive with fetch(..., {mode:
// 'no-cors'}) and a text/plain body (no preflight), and read telemetry over a WebSocket - and reports what it saw. The
// robot's side (was it cleared? did it move? what did it log?) is checked by the test that runs this script.
//
// Usage: node origin_probe.mjs PAGE ROBOT_URL [TOKEN]
//   PAGE  "hostile": a page this script serves itself from another loopback port (another origin);
//         any URL: the browser opens it and runs the same from there (the robot's own origin, or a rebinding name).
//   TOKEN put in the WebSocket's ?token= (what a page that knows a token can do) and, on the robot's own origin only,
//         in an Authorization header (a cross-origin page cannot send one without a CORS preflight).
// Prints one JSON line: {"page", "read", "clear", "move", "ws", "frames"}: the HTTP status of GET /api/status,
// POST /api/estop/clear and POST /api/action as the page can read it (0 when the answer is opaque to it, -1 for a
// network error), and "open" or "refused" for the WebSocket.
import { chromium } from 'playwright-core';
import { createServer } from 'node:http';

const [pageArg, robot, token = ''] = process.argv.slice(2);

let hostile = null;
let pageUrl = pageArg;
if (pageArg === 'hostile') {
  hostile = createServer((request, response) => {
    response.writeHead(200, { 'Content-Type': 'text/html' });
    response.end('<!doctype html><title>another origin</title><p>nothing to see here</p>');
  });
  await new Promise((resolve) => hostile.listen(0, '127.0.0.1', resolve));
  pageUrl = `http://127.0.0.1:${hostile.address().port}/`;
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync',
         // A name that resolves to the robot, as a DNS rebinding attack makes evil.test do.
         '--host-resolver-rules=MAP evil.test 127.0.0.1'],
});
let exitCode = 0;
try {
  const context = await browser.newContext();
  const page = await context.newPage();
  await page.goto(pageUrl);
  const result = await page.evaluate(async ({ robot, token }) => {
    const own = new URL(robot).origin === location.origin;
    const post = async (path, body) => {
      // What the hostile page did: no preflight, so the request reaches the robot; the answer is opaque to it.
      const init = own ? { method: 'POST', body, headers: token ? { Authorization: `Bearer ${token}` } : {} }
                       : { method: 'POST', body, mode: 'no-cors' };
      try {
        const response = await fetch(robot + path, init);
        return response.status;
      } catch (e) {
        return -1;  // a network error (the connection refused or reset)
      }
    };
    // A same-origin GET carries no Origin: what a DNS-rebinding page reads (its answer is the page's to read).
    let read = 0;
    try {
      read = (await fetch(robot + '/api/status', own ? { headers: token ? { Authorization: `Bearer ${token}` } : {} }
                                                     : { mode: 'no-cors' })).status;
    } catch (e) {
      read = -1;
    }
    const clear = await post('/api/estop/clear', '{}');
    const move = await post('/api/action', JSON.stringify({ type: 'move', linear: 0.3, angular: 0, duration_ms: 1000 }));
    const ws = await new Promise((resolve) => {
      const url = robot.replace(/^http/, 'ws') + '/ws/telemetry' + (token ? `?token=${encodeURIComponent(token)}` : '');
      const socket = new WebSocket(url);
      let frames = 0, opened = false;
      const done = () => resolve({ ws: opened ? 'open' : 'refused', frames });
      socket.onopen = () => { opened = true; };
      socket.onmessage = () => { if (++frames >= 2) { socket.close(); done(); } };
      socket.onerror = () => {};
      socket.onclose = done;
      setTimeout(() => { socket.close(); done(); }, 5000);
    });
    return { page: location.origin, read, clear, move, ...ws };
  }, { robot, token });
  console.log(JSON.stringify(result));
} catch (e) {
  console.error(`FAILED: ${e.message}`);
  exitCode = 1;
} finally {
  await browser.close();
  if (hostile) hostile.close();
}
process.exit(exitCode);
