// The robot's state is impossible to miss (issue 29 item 4), in Debian's headless Chromium (playwright-core), on a
// robot whose arm driver failed (a Dynamixel on a port that does not exist) and one of whose two drives failed:
// the error badge is red, the degraded capability amber, each failed driver and capability shows its reason where it
// is listed; a latched robot shows a red banner with who stopped it, when and why in words, on a desktop and on a
// 390x844 phone, still there after scrolling to the bottom; "Clear e-stop" shows only while latched, only for owners.
// The colour checks read the pixels of the screenshots they take (each also lands in SHOTS).
// Usage: node state.mjs BASE_URL OWNER_TOKEN GUEST_TOKEN SHOTS_DIR MISSING_PORT   (exit 0: every check held)
import { chromium } from 'playwright-core';
import { mkdirSync, writeFileSync } from 'node:fs';

const [base, ownerToken, guestToken, shots, missingPort] = process.argv.slice(2);
mkdirSync(shots, { recursive: true });

function check(what, ok, detail = '') {
  if (!ok) throw new Error(`${what} ${detail}`);
  console.log(`ok - ${what} ${detail}`);
}
async function robot(method, path, token, body) {
  const init = { method, headers: { Authorization: `Bearer ${token}` } };
  if (body !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  return (await fetch(base + path, init)).json();
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync'],
});
// The screenshots are decoded by the browser itself (an <img> drawn on a canvas): no PNG code here.
const decoder = await (await browser.newContext()).newPage();
async function pixel(png, x, y) {
  return decoder.evaluate(async ({ b64, x, y }) => {
    const img = new Image();
    img.src = `data:image/png;base64,${b64}`;
    await img.decode();
    const canvas = document.createElement('canvas');
    canvas.width = img.width;
    canvas.height = img.height;
    const g = canvas.getContext('2d');
    g.drawImage(img, 0, 0);
    return Array.from(g.getImageData(Math.round(x), Math.round(y), 1, 1).data.slice(0, 3));
  }, { b64: png.toString('base64'), x, y });
}
const isRed = ([r, g, b]) => r > 170 && g < 90 && b < 90;
async function shot(page, name) {
  const png = await page.screenshot();  // the viewport, as the operator sees it
  writeFileSync(`${shots}/${name}`, png);
  return png;
}
// A point inside the element's padding (not on its text), in viewport pixels.
async function paddingPoint(page, selector) {
  const box = await (await page.$(selector)).boundingBox();
  return [box.x + 3, box.y + 3];
}

// The lists are re-rendered on every health update, so a handle taken in one round trip may be detached by the next
// (its computed colour is then ''): look the element up and read its colour in one evaluation.
async function colourOf(page, selector) {
  return page.evaluate((sel) => getComputedStyle(document.querySelector(sel)).color, selector);
}

async function open(viewport, token) {
  const context = await browser.newContext({ viewport, deviceScaleFactor: 1, isMobile: viewport.width < 500,
                                             hasTouch: viewport.width < 500 });
  const page = await context.newPage();
  page.on('pageerror', (e) => { console.error(`page error: ${e.message}`); pageErrors += 1; });
  await page.goto(base + '/');
  await page.fill('#token', token);
  await page.click('#login-form button');
  await page.waitForSelector('#app:not([hidden])');
  await page.waitForFunction(() => document.getElementById('link').textContent === 'live', null, { timeout: 5000 });
  return page;
}

let failed = false;
let pageErrors = 0;
try {
  // 1. Desktop, owner, not latched: the error badge is red, no banner, no clear; the failures say why in their rows.
  const page = await open({ width: 1280, height: 900 }, ownerToken);
  await page.waitForSelector('#drivers li[data-name=arm0] .why:not(:empty)');
  await page.waitForFunction(() => !document.querySelector('#drivers li[data-name=arm0] .why').textContent.startsWith('…'));
  check('the robot state is error', (await page.textContent('#state')) === 'error');
  check('no banner while not latched', await page.isHidden('#banner'));
  check('no clear button while not latched', await page.isHidden('#clear'));
  const arm0 = await page.textContent('#drivers li[data-name=arm0]');
  check('the failed driver shows its reason, device and hint in its row',
        arm0.includes(`cannot open ${missingPort}`) && arm0.includes('U2D2'), arm0);
  const arm = await page.textContent('#capabilities li[data-name=arm]');
  check('the capability that needs it shows error and why', arm.includes('error') && arm.includes('arm0 (dynamixel)'), arm);
  const teleop = await page.$eval('#capabilities li[data-name=teleop]', (li) => [li.dataset.state, li.textContent]);
  check('the capability that lost one of its drives is degraded, naming the drive',
        teleop[0] === 'degraded' && teleop[1].includes('drive1'), teleop[1]);
  let png = await shot(page, 'state-1-error.png');
  const badge = await (await page.$('#state')).boundingBox();  // a pill: left of the text, inside the round end
  check('the error badge is red (pixels)', isRed(await pixel(png, badge.x + 5, badge.y + badge.height / 2)));
  const amber = await colourOf(page, '#capabilities li[data-name=teleop]');
  check('degraded is amber', amber === 'rgb(179, 107, 0)', amber);
  const driverColour = await colourOf(page, '#drivers li[data-name=arm0]');
  check('a failed driver is red', isRed(driverColour.match(/\d+/g).map(Number)), driverColour);

  // 2. STOP: the red banner says who stopped it, when and why; clear appears (owner).
  await page.click('#estop');
  await page.waitForSelector('#banner:not([hidden])', { timeout: 2000 });
  const banner = await page.textContent('#banner');
  check('the banner says who, when and why in words',
        /STOPPED at \d{1,2}:\d{2}:\d{2}/.test(banner) && banner.includes('Stopped by owner-principal from the dashboard'), banner);
  check('clear shows while latched, for the owner', await page.isVisible('#clear'));
  png = await shot(page, 'state-2-latched-desktop.png');
  check('the banner is red across the page (pixels)', isRed(await pixel(png, ...(await paddingPoint(page, '#banner')))) &&
        isRed(await pixel(png, 1270, (await paddingPoint(page, '#banner'))[1])));

  // 3. Clear: the banner and the clear button go.
  await page.click('#clear');
  await page.waitForSelector('#banner[hidden]', { state: 'attached', timeout: 2000 });
  check('after clear: no banner, no clear button', await page.isHidden('#clear'));
  png = await shot(page, 'state-3-cleared-desktop.png');
  check('no red where the banner was (pixels)', !isRed(await pixel(png, 1270, 3 + (await (await page.$('header')).boundingBox()).height)));

  // 4. A phone, a guest: latched by someone else, the banner is there, red, and still there after scrolling down.
  const phone = await open({ width: 390, height: 844 }, guestToken);
  check('the guest sees no clear button', await phone.isHidden('#clear'));
  await robot('POST', '/api/stop', ownerToken, { reason: 'checking the phone', from: 'rcanctl' });
  await phone.waitForSelector('#banner:not([hidden])', { timeout: 2000 });
  const phoneBanner = await phone.textContent('#banner');
  check('the phone banner says who and why', phoneBanner.includes('Stopped by owner-principal from rcanctl: checking the phone'),
        phoneBanner);
  check('no clear button for a guest while latched', await phone.isHidden('#clear'));
  await phone.evaluate(() => window.scrollTo(0, document.documentElement.scrollHeight));
  await phone.waitForFunction(() => window.scrollY > 200);
  const scrolled = await phone.evaluate(() => window.scrollY);
  png = await shot(phone, 'state-4-latched-phone-scrolled.png');
  const bannerBox = await (await phone.$('#banner')).boundingBox();
  check('the banner stays at the top of a scrolled phone', bannerBox.y >= 0 && bannerBox.y < 5, `scrollY ${scrolled}`);
  check('and it is red there (pixels)', isRed(await pixel(png, 3, bannerBox.y + 3)) && isRed(await pixel(png, 386, bannerBox.y + 3)));

  // 5. The owner on a phone: clear shows while latched; after clear neither it nor the banner.
  const ownerPhone = await open({ width: 390, height: 844 }, ownerToken);
  await ownerPhone.waitForSelector('#banner:not([hidden])', { timeout: 2000 });
  check('clear shows for the owner on a phone while latched', await ownerPhone.isVisible('#clear'));
  await shot(ownerPhone, 'state-5-owner-phone.png');
  await ownerPhone.click('#clear');
  await phone.waitForSelector('#banner[hidden]', { state: 'attached', timeout: 2000 });
  check('the guest phone sees the clear', await phone.isHidden('#banner'));
  png = await shot(phone, 'state-6-cleared-phone.png');
  check('no red banner on the cleared phone (pixels)', !isRed(await pixel(png, 386, 3)));
  check('no script error on any page', pageErrors === 0);
} catch (e) {
  console.error(`FAILED: ${e.message}`);
  failed = true;
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
