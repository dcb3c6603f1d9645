// rcand's dashboard: plain JavaScript, no dependencies, served by rcand itself (works on an offline LAN).
// State comes from WS /ws/telemetry (a frame every 200 ms, pushed at once on an e-stop); details from the HTTP API.
'use strict';

const $ = (id) => document.getElementById(id);
const DRIVE_PERIOD_MS = 100;  // a held pad re-sends its move this often...
const DRIVE_LEASE_MS = 300;   // ...and each move lasts this long: a lost link stops the robot within it

let token = sessionStorage.getItem('rcand.token') || localStorage.getItem('rcand.token') || '';
let session = null;      // GET /api/session: principal, role, scopes
let declared = new Set();
let socket = null;
let retryTimer = null;
let drive = null;        // the held pad direction: {linear, angular, timer, button}
let details = { capabilities: {}, drivers: {} };  // GET /api/status's items by name: state, reason, device, hint
let detailsPending = false;

// ---- HTTP ----------------------------------------------------------------------------------------------------------
async function api(method, path, body) {
  const init = { method, headers: { Authorization: `Bearer ${token}` } };
  if (body !== undefined) {
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  const response = await fetch(path, init);
  let json = null;
  try { json = await response.json(); } catch (_) { /* an empty or non-JSON answer */ }
  return { status: response.status, body: json || {} };
}

function toast(text) {
  const el = $('toast');
  el.textContent = text;
  el.hidden = false;
  clearTimeout(toast.timer);
  toast.timer = setTimeout(() => { el.hidden = true; }, 4000);
}

function failure(what, answer) {
  const body = answer.body || {};
  toast(`${what}: ${answer.status} ${body.code || ''} ${body.error || ''}`.trim());
}

function cell(row, text) {
  const td = document.createElement('td');
  td.textContent = text === null || text === undefined ? '–' : String(text);
  row.appendChild(td);
}

function table(el, headers, rows) {
  el.replaceChildren();
  const head = el.insertRow();
  for (const h of headers) {
    const th = document.createElement('th');
    th.textContent = h;
    head.appendChild(th);
  }
  for (const r of rows) {
    const tr = el.insertRow();
    for (const value of r) cell(tr, value);
  }
}

// ---- login ---------------------------------------------------------------------------------------------------------
async function login(candidate, remember) {
  token = candidate;
  let answer;
  try {
    answer = await api('GET', '/api/session');
  } catch (e) {
    $('login-error').textContent = `rcand cannot be reached: ${e.message}`;
    return false;
  }
  if (answer.status !== 200) {
    $('login-error').textContent = answer.body.error || `refused (${answer.status})`;
    token = '';
    return false;
  }
  session = answer.body;
  (remember ? localStorage : sessionStorage).setItem('rcand.token', token);
  $('login').hidden = true;
  $('app').hidden = false;
  $('who').textContent = `${session.principal} (${session.role})`;
  await loadStatus();
  connect();
  refreshAudit();
  refreshPeers();
  refreshSwarm();
  return true;
}

function logout() {
  stopDriving();
  sessionStorage.removeItem('rcand.token');
  localStorage.removeItem('rcand.token');
  token = '';
  if (socket) socket.close();
  location.reload();
}

// ---- status --------------------------------------------------------------------------------------------------------
async function loadStatus() {
  const answer = await api('GET', '/api/status');
  if (answer.status !== 200) return failure('status', answer);
  const s = answer.body;
  $('robot-name').textContent = s.name || 'robot';
  document.title = `rcand · ${s.name || 'robot'}`;
  declared = new Set(Object.keys(s.capabilities || {}));
  const facts = $('facts');
  facts.replaceChildren();
  for (const [k, v] of [['RURI', s.ruri], ['rcand', s.version], ['RCAN', s.rcan_version]]) {
    const dt = document.createElement('dt');
    dt.textContent = k;
    const dd = document.createElement('dd');
    dd.textContent = v;
    facts.append(dt, dd);
  }
  $('teleop-card').hidden = !declared.has('teleop');
  $('nav-card').hidden = !declared.has('nav');
  $('chat-card').hidden = !declared.has('chat');
  $('arm-card').hidden = !declared.has('arm');
  $('vision-card').hidden = !declared.has('vision');
  // <img> cannot send headers: the stream takes ?token= (docs/protocol.md §3).
  if (declared.has('vision')) $('camera').src = `/api/stream/mjpeg?token=${encodeURIComponent(token)}`;
  if (declared.has('arm')) refreshArm();
  keepDetails(s);
  const estopAnswer = s.estopped ? await api('GET', '/api/estop') : null;  // who stopped it, for the banner
  showFrame({ estopped: s.estopped, state: s.state, pose: s.pose, nav_running: s.nav_running,
              estop: estopAnswer && estopAnswer.status === 200 ? estopAnswer.body : null,
              capabilities: Object.fromEntries(Object.entries(s.capabilities || {}).map(([k, v]) => [k, itemState(v)])),
              drivers: Object.fromEntries((s.drivers || []).map((d) => [d.id, itemState(d)])) });
}

// ---- health: each capability and driver with its state, and why when it is not ok (docs/protocol.md §7.2) ------------
function itemState(item) {
  if (['failed', 'error', 'degraded'].includes(item.state)) return item.state;
  return item.stale ? 'stale' : 'ok';
}

function keepDetails(s) {
  details = { capabilities: s.capabilities || {},
              drivers: Object.fromEntries((s.drivers || []).map((d) => [d.id, d])) };
}

// A frame carries states only; when one differs from what the reasons were read with, read them again.
async function refreshDetails() {
  if (detailsPending || Date.now() - refreshDetails.lastMs < 1000) return;  // at most once a second
  refreshDetails.lastMs = Date.now();
  detailsPending = true;
  try {
    const answer = await api('GET', '/api/status');
    if (answer.status === 200) keepDetails(answer.body);
  } finally {
    detailsPending = false;
  }
  renderHealth($('capabilities'), showFrame.capabilities, details.capabilities);
  renderHealth($('drivers'), showFrame.drivers, details.drivers);
}

refreshDetails.lastMs = 0;

function whyText(item) {
  if (!item || !item.reason) return '';
  const parts = [item.reason];
  if (item.hint) parts.push(`Try: ${item.hint}`);
  return parts.join(' — ');
}

// Returns false when a state shown has no reason read for it yet.
function renderHealth(el, states, known) {
  el.replaceChildren();
  let complete = true;
  for (const [name, state] of Object.entries(states || {})) {
    const item = known[name];
    const li = document.createElement('li');
    li.dataset.name = name;
    li.dataset.state = state;
    const label = document.createElement('span');
    label.className = 'name';
    label.textContent = name;
    const tag = document.createElement('span');
    tag.className = 'state';
    tag.textContent = state;
    li.append(label, tag);
    if (state !== 'ok' && state !== 'stale') {
      if (!item || itemState(item) !== state) complete = false;
      const why = document.createElement('p');
      why.className = 'why';
      why.textContent = item && itemState(item) === state ? whyText(item) : '…';
      li.appendChild(why);
    }
    el.appendChild(li);
  }
  return complete;
}

function canClear() { return !!session && (session.role === 'OWNER' || session.role === 'CREATOR'); }

// The latch banner: who stopped the robot, when, and why, in words (GET /api/estop's "summary" and "since_ms").
function showLatch(latched, estop) {
  $('banner').hidden = !latched;
  $('clear').hidden = !(latched && canClear());
  if (!latched) return;
  const when = estop && estop.since_ms ? new Date(estop.since_ms).toLocaleTimeString() : null;
  $('banner-title').textContent = when ? `STOPPED at ${when}` : 'STOPPED';
  $('banner-text').textContent = estop ? (estop.summary || estop.reason || '') : '';
  $('banner-text').textContent += canClear() ? '. Nothing moves until you clear the e-stop.'
                                              : '. Nothing moves until an owner clears the e-stop.';
}

function showFrame(f) {
  const latched = !!f.estopped;
  document.body.dataset.estopped = latched;
  const state = latched ? 'estop' : (f.state || 'idle');
  $('state').textContent = latched ? 'E-STOPPED' : state;
  $('state').className = `badge state-${state}${latched ? ' latched' : ''}`;
  $('state').dataset.state = state;
  $('estop').classList.toggle('latched', latched);
  showLatch(latched, f.estop);
  if (latched) stopDriving();
  if (f.capabilities) showFrame.capabilities = f.capabilities;
  if (f.drivers) showFrame.drivers = f.drivers;
  const complete = renderHealth($('capabilities'), showFrame.capabilities, details.capabilities) &
                   renderHealth($('drivers'), showFrame.drivers, details.drivers);
  if (!complete) refreshDetails();
  if (f.pose) {
    $('pose').textContent = `pose x ${f.pose.x_m.toFixed(2)} m, y ${f.pose.y_m.toFixed(2)} m, ` +
                            `heading ${f.pose.heading_deg.toFixed(0)}°`;
  }
  if (f.nav_running || showFrame.navWasRunning) refreshNav();
  showFrame.navWasRunning = !!f.nav_running;
}

// ---- live telemetry ------------------------------------------------------------------------------------------------
function setLink(up) {
  $('link').textContent = up ? 'live' : 'offline';
  $('link').className = `badge ${up ? '' : 'off'}`;
}

function connect() {
  clearTimeout(retryTimer);
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  socket = new WebSocket(`${scheme}://${location.host}/ws/telemetry?token=${encodeURIComponent(token)}`);
  socket.onopen = () => setLink(true);
  socket.onmessage = (event) => {
    let frame;
    try { frame = JSON.parse(event.data); } catch (_) { return; }
    if (frame.type === 'telemetry') showFrame(frame);
  };
  socket.onclose = () => {
    setLink(false);
    stopDriving();  // no live link, no driving: the operator cannot see what the robot does
    if (token) retryTimer = setTimeout(connect, 1000);
  };
}

// ---- e-stop --------------------------------------------------------------------------------------------------------
async function estop() {
  stopDriving();
  // The WebSocket is already open: a stop there skips the TCP and HTTP set-up. HTTP as well, in case it is not.
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({ cmd: 'stop', from: 'the dashboard' }));
  const answer = await api('POST', '/api/stop', { from: 'the dashboard' });
  if (answer.status !== 200) failure('stop', answer);
}

async function clearEstop() {
  const answer = await api('POST', '/api/estop/clear', {});
  if (answer.status !== 200) failure('clear', answer);
}

// ---- teleop pad ----------------------------------------------------------------------------------------------------
const DIRECTIONS = { forward: [1, 0], back: [-1, 0], left: [0, 1], right: [0, -1] };

function sendMove(linear, angular, duration) {
  return api('POST', '/api/action', { type: 'move', linear, angular, duration_ms: duration })
    .then((answer) => { if (answer.status !== 200) { failure('move', answer); stopDriving(); } })
    .catch(() => stopDriving());
}

function startDriving(direction, button) {
  if (drive) stopDriving();
  if (!socket || socket.readyState !== WebSocket.OPEN) return toast('no live link: not driving');
  const speed = Number($('speed').value);
  const [l, a] = DIRECTIONS[direction];
  drive = { linear: l * speed, angular: a * speed, button };
  if (button) button.classList.add('held');
  sendMove(drive.linear, drive.angular, DRIVE_LEASE_MS);
  drive.timer = setInterval(() => sendMove(drive.linear, drive.angular, DRIVE_LEASE_MS), DRIVE_PERIOD_MS);
}

function stopDriving() {
  if (!drive) return;
  clearInterval(drive.timer);
  if (drive.button) drive.button.classList.remove('held');
  drive = null;
  sendMove(0, 0, 1);  // stop now rather than when the last lease runs out
}

function bindPad() {
  for (const button of document.querySelectorAll('[data-drive]')) {
    button.addEventListener('pointerdown', (e) => {
      e.preventDefault();
      button.setPointerCapture(e.pointerId);
      startDriving(button.dataset.drive, button);
    });
    for (const end of ['pointerup', 'pointercancel', 'lostpointercapture']) button.addEventListener(end, stopDriving);
  }
  $('speed').addEventListener('input', () => { $('speed-value').textContent = $('speed').value; });
  window.addEventListener('blur', stopDriving);
  document.addEventListener('visibilitychange', () => { if (document.hidden) stopDriving(); });
  window.addEventListener('offline', stopDriving);
}

// ---- keyboard: Space or Escape stops, arrows drive while held --------------------------------------------------------
const KEYS = { ArrowUp: 'forward', ArrowDown: 'back', ArrowLeft: 'left', ArrowRight: 'right' };
function bindKeys() {
  document.addEventListener('keydown', (e) => {
    if ($('app').hidden || e.target.tagName === 'INPUT') return;
    if (e.key === ' ' || e.key === 'Escape') {
      e.preventDefault();
      estop();
    } else if (KEYS[e.key] && !e.repeat && declared.has('teleop')) {
      e.preventDefault();
      startDriving(KEYS[e.key], null);
    }
  });
  document.addEventListener('keyup', (e) => { if (KEYS[e.key]) stopDriving(); });
}

// ---- nav -----------------------------------------------------------------------------------------------------------
async function refreshNav() {
  const answer = await api('GET', '/api/nav/status');
  if (answer.status !== 200) return;
  const s = answer.body;
  const progress = s.eta_ms ? Math.min(1, (s.elapsed_ms || 0) / s.eta_ms) : (s.state === 'done' ? 1 : 0);
  $('nav-progress').value = progress;
  const result = s.result ? ` — ${s.result.ok === false ? 'failed' : 'result'}: ${s.result.message || s.result.reason || ''}` : '';
  $('nav-status').textContent = `job ${s.job_id || '–'}: ${s.state}${result}`;
}

async function submitNav(e) {
  e.preventDefault();
  const form = new FormData($('nav-form'));
  const body = Object.fromEntries([...form.entries()].map(([k, v]) => [k, Number(v)]));
  const answer = await api('POST', '/api/nav/waypoint', body);
  if (answer.status !== 200) return failure('waypoint', answer);
  refreshNav();
}

// ---- chat, arm, peers, audit ----------------------------------------------------------------------------------------
async function submitChat(e) {
  e.preventDefault();
  const instruction = $('chat-input').value;
  const li = document.createElement('li');
  li.textContent = `> ${instruction}`;
  $('chat-log').prepend(li);
  const answer = await api('POST', '/api/command', { instruction });
  const reply = document.createElement('li');
  reply.textContent = answer.status === 200
    ? `${answer.body.raw_text || ''} [${answer.body.brain || ''}]`
    : `${answer.status} ${answer.body.error || ''}`;
  $('chat-log').prepend(reply);
  $('chat-input').value = '';
}

async function refreshArm() {
  const answer = await api('GET', '/api/arm/joints');
  if (answer.status !== 200) return;
  const fixed = (x) => (typeof x === 'number' ? x.toFixed(1) : x);
  const rows = (answer.body.joints || []).map((j) => [j.joint, fixed(j.position_deg), fixed(j.target_deg),
                                                      j.limits ? `${j.limits.min_deg} … ${j.limits.max_deg}` : null]);
  table($('arm-joints'), ['joint', 'position °', 'target °', 'limits °'], rows);
}

async function refreshPeers() {
  const answer = await api('GET', '/api/r2r/peers');
  if (answer.status !== 200) {
    table($('peers'), ['R2R'], [[answer.body.error || `unavailable (${answer.status})`]]);
    return;
  }
  const peers = answer.body.peers || [];
  table($('peers'), ['peer', 'transport', 'last seen'],
        peers.map((p) => [p.id || p.name, p.transport, p.last_seen_ms ? new Date(p.last_seen_ms).toLocaleTimeString() : null]));
}

// The swarm table: each node of swarm.yaml, probed by rcand (GET /api/swarm), with a stop for that node alone.
function swarmState(n) {
  if (!n.reachable) return `unreachable: ${n.error || ''}`;
  if (n.error) return n.error;
  return n.estopped ? 'E-STOPPED' : (n.state || 'ok');
}

async function refreshSwarm() {
  const answer = await api('GET', '/api/swarm');
  const nodes = answer.status === 200 ? answer.body.nodes || [] : [];
  $('swarm-card').hidden = nodes.length === 0;
  table($('swarm'), ['node', 'address', 'state', ''], []);
  for (const n of nodes) {
    const tr = $('swarm').insertRow();
    tr.dataset.node = n.name;
    tr.dataset.state = !n.reachable ? 'unreachable' : n.estopped ? 'estopped' : 'ok';
    cell(tr, n.self ? `${n.name} (this robot)` : n.name);
    cell(tr, n.address);
    cell(tr, swarmState(n));
    const td = document.createElement('td');
    const stop = document.createElement('button');
    stop.className = 'node-stop';
    stop.textContent = 'Stop';
    stop.title = `e-stop ${n.name} only`;
    stop.addEventListener('click', () => stopNode(n.name));
    td.appendChild(stop);
    tr.appendChild(td);
  }
}

async function stopNode(name) {
  const answer = await api('POST', `/api/swarm/${encodeURIComponent(name)}/stop`,
                           { reason: `dashboard (${session ? session.principal : '?'})` });
  if (answer.status !== 200) failure(`stop ${name}`, answer);
  else toast(`${name} stopped`);
  refreshSwarm();
}

async function refreshAudit() {
  const answer = await api('GET', '/api/audit?limit=20');
  if (answer.status !== 200) {
    table($('audit'), ['audit'], [[answer.body.error || `unavailable (${answer.status})`]]);
    return;
  }
  const entries = (answer.body.entries || []).slice().reverse();
  table($('audit'), ['#', 'time', 'principal', 'event', 'outcome'],
        entries.map((e) => [e.seq, e.timestamp_ms ? new Date(e.timestamp_ms).toLocaleTimeString() : e.ts, e.principal,
                            e.count > 1 ? `${e.event} (x${e.count})` : e.event, e.outcome]));  // repeated stops: one entry
}

// ---- start ---------------------------------------------------------------------------------------------------------
document.addEventListener('DOMContentLoaded', () => {
  $('login-form').addEventListener('submit', (e) => {
    e.preventDefault();
    login($('token').value.trim(), $('remember').checked);
  });
  $('logout').addEventListener('click', logout);
  $('estop').addEventListener('click', estop);
  $('clear').addEventListener('click', clearEstop);
  $('nav-form').addEventListener('submit', submitNav);
  $('nav-cancel').addEventListener('click', () => api('POST', '/api/nav/cancel', {}).then(refreshNav));
  $('chat-form').addEventListener('submit', submitChat);
  $('audit-refresh').addEventListener('click', refreshAudit);
  bindPad();
  bindKeys();
  setInterval(() => { if (!$('app').hidden && !document.hidden) { refreshAudit(); refreshPeers(); refreshSwarm(); if (declared.has('arm')) refreshArm(); } }, 5000);
  if (token) login(token, !!localStorage.getItem('rcand.token'));
});
