// First paint of the dashboard on loopback (issue 18: < 500 ms): each load in a fresh browser context (no cache),
// timed by Chromium's own paint timing; prints the median and p99 over the loads, and the same for DOMContentLoaded.
// Usage (from a folder with playwright-core installed): node dashboard_first_paint.mjs BASE_URL [LOADS]
import { chromium } from 'playwright-core';

const [base, loadsArg] = process.argv.slice(2);
const loads = Number(loadsArg || 50);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync'],
});
const paint = [], ready = [];
for (let i = 0; i < loads; ++i) {
  const context = await browser.newContext();
  const page = await context.newPage();
  await page.goto(base + '/', { waitUntil: 'load' });
  const t = await page.evaluate(() => new Promise((resolve) => {
    const nav = performance.getEntriesByType('navigation')[0];
    const done = (fcp) => resolve({ fcp, dcl: nav.domContentLoadedEventEnd });
    const seen = performance.getEntriesByName('first-contentful-paint')[0];
    if (seen) return done(seen.startTime);
    new PerformanceObserver((list) => done(list.getEntries()[0].startTime)).observe({ type: 'paint', buffered: true });
  }));
  paint.push(t.fcp);
  ready.push(t.dcl);
  await context.close();
}
await browser.close();
const pct = (xs, p) => { const s = [...xs].sort((a, b) => a - b); return s[Math.min(s.length - 1, Math.floor(p * s.length))]; };
const f = (x) => x.toFixed(1);
console.log(`dashboard first contentful paint over ${loads} cold loads: median ${f(pct(paint, 0.5))} ms, p99 ${f(pct(paint, 0.99))} ms`);
console.log(`DOMContentLoaded: median ${f(pct(ready, 0.5))} ms, p99 ${f(pct(ready, 0.99))} ms`);
