// gimbal-web's page: sign-in, then one card per gimbal, its state pushed
// by server-sent events (/api/events). Every text from the server goes
// into the page as text (textContent, setAttribute), never as markup.
// A held button or arrow key moves the gimbal for the door's lease
// (lease_ms), renewed here every third of it while held: when the page
// stops renewing (released, closed, killed, cut off), gimbal-web stops
// the gimbal when the lease runs out.
'use strict';

const ARROWS = {
  ArrowLeft: [-1, 0],
  ArrowRight: [1, 0],
  ArrowUp: [0, 1],
  ArrowDown: [0, -1],
};

let me = null; // /api/session
let cards = [];
let held = null; // { g, pan, tilt, timer }
let events = null;

const byId = (id) => document.getElementById(id);

async function api(path, body, keepalive) {
  const response = await fetch(path, {
    method: 'POST',
    credentials: 'same-origin',
    keepalive: Boolean(keepalive),
    headers: { 'Content-Type': 'application/json', 'X-CSRF-Token': me ? me.csrf : '' },
    body: JSON.stringify(body),
  });
  let answer = {};
  try {
    answer = await response.json();
  } catch (e) {
    answer = {};
  }
  if (!response.ok) {
    throw new Error(answer.error || `${response.status} ${response.statusText}`);
  }
  return answer;
}

// A refusal or failure stays on its card with the time it came, until
// the gimbal's state (online, motion, who controls it) has changed since
// and it has been shown for at least REFUSAL_SHOWN_MS.
const REFUSAL_SHOWN_MS = 5000;

function stateKey(s) {
  return s ? JSON.stringify([s.online, s.motion, s.control]) : '';
}

function showError(i, text) {
  const card = cards[i];
  if (!card) return;
  const when = document.createElement('span');
  when.className = 'when';
  when.textContent = ` (${new Date().toLocaleTimeString([], { hour12: false })})`;
  card.error.replaceChildren(document.createTextNode(text), when);
  card.errorKey = stateKey(card.last);
  card.errorAt = Date.now();
  clearTimeout(card.errorTimer);
  card.errorTimer = setTimeout(() => clearStaleError(card), REFUSAL_SHOWN_MS + 50);
}

function clearError(i) {
  if (cards[i]) {
    cards[i].error.replaceChildren();
    cards[i].errorKey = null;
  }
}

function clearStaleError(card) {
  if (card.errorKey === null || card.errorKey === undefined) return;
  if (Date.now() - card.errorAt < REFUSAL_SHOWN_MS) return;
  if (stateKey(card.last) !== card.errorKey) {
    card.error.replaceChildren();
    card.errorKey = null;
  }
}

// Grid spacing of the map in degrees: the finest of these that draws at
// most 12 lines across the pan travel.
function gridStep(span) {
  return [5, 10, 15, 30, 45, 90, 180].find((step) => span / step <= 12) || 360;
}

// The map's grid, axis labels and scale (the SVG stretches, so its words
// are page text around it): pan grows to the right (clockwise seen from
// above), tilt upward, as gcud's degrees.
function drawScale(card, q) {
  const [p0, p1] = card.g.pan_deg;
  const [t0, t1] = card.g.tilt_deg;
  const step = gridStep(p1 - p0);
  const grid = q('.grid');
  for (let p = Math.ceil(p0 / step) * step; p <= p1; p += step) {
    if (p === 0) continue;
    const line = document.createElementNS('http://www.w3.org/2000/svg', 'line');
    svg(line, { x1: p, x2: p, y1: -t1, y2: -t0 });
    grid.appendChild(line);
  }
  for (let t = Math.ceil(t0 / step) * step; t <= t1; t += step) {
    if (t === 0) continue;
    const line = document.createElementNS('http://www.w3.org/2000/svg', 'line');
    svg(line, { x1: p0, x2: p1, y1: -t, y2: -t });
    grid.appendChild(line);
  }
  q('.map-tilt-hi').textContent = `↑ tilt ${t1}° (up)`;
  q('.map-tilt-lo').textContent = `↓ tilt ${t0}° (down)`;
  q('.map-pan-lo').textContent = `← pan ${p0}° (left)`;
  q('.map-pan-hi').textContent = `pan ${p1}° (right) →`;
  q('.map-key').textContent = `grid every ${step}°, lines through 0°`;
  q('.picture').setAttribute(
    'aria-description',
    `pan ${p0}° to ${p1}° left to right, tilt ${t0}° to ${t1}° bottom to top, grid every ${step}°`,
  );
}

function act(i, path, body) {
  return api(path, Object.assign({ gimbal: i }, body || {}))
    .then((answer) => {
      clearError(i);
      return answer;
    })
    .catch((e) => showError(i, e.message));
}

function hold(i, pan, tilt) {
  if (held && held.g === i && held.pan === pan && held.tilt === tilt) return;
  release();
  const h = { g: i, pan, tilt, timer: null };
  held = h;
  const send = () => {
    if (held !== h) return;
    api('/api/move', { gimbal: i, pan, tilt, speed: Number(cards[i].speed.value) })
      .then(() => {
        if (held === h) clearError(i);
      })
      .catch((e) => {
        showError(i, e.message);
        // Refused (gcud: another link holds the gimbal, a limit) or not
        // delivered: the hold ends here, without a stop: nothing of this
        // page moves, and a stop would end the holder's motion.
        if (held === h) release(false);
      });
  };
  send();
  h.timer = setInterval(send, Math.max(50, Math.floor(me.lease_ms / 3)));
}

function release(stop = true) {
  if (!held) return;
  const h = held;
  held = null;
  clearInterval(h.timer);
  if (stop) api('/api/stop', { gimbal: h.g }, true).catch((e) => showError(h.g, e.message));
}

function svg(el, attrs) {
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
}

function buildCard(g, i) {
  const node = byId('card').content.firstElementChild.cloneNode(true);
  node.setAttribute('aria-label', g.name);
  const q = (s) => node.querySelector(s);
  const card = {
    node,
    name: q('.name'),
    state: q('.state'),
    control: q('.control'),
    position: q('.position'),
    error: q('.error'),
    picture: q('.picture'),
    dot: q('.dot'),
    limits: q('.limits'),
    zones: q('.zones'),
    rulesText: q('.rules-text'),
    outcome: q('.outcome'),
    rulesShown: '',
    speed: q('.speed'),
    presetName: q('.preset-name'),
    presetList: q('.preset-list'),
    presetsShown: '',
    release: q('.release'),
    last: null,
    errorKey: null,
    errorAt: 0,
    errorTimer: null,
    g,
  };
  card.name.textContent = `${g.name} (${g.address})`;
  const [p0, p1] = g.pan_deg;
  const [t0, t1] = g.tilt_deg;
  svg(card.picture, { viewBox: `${p0} ${-t1} ${p1 - p0} ${t1 - t0}` });
  svg(q('.travel'), { x: p0, y: -t1, width: p1 - p0, height: t1 - t0 });
  svg(q('.pan-zero'), { x1: 0, x2: 0, y1: -t1, y2: -t0 });
  svg(q('.tilt-zero'), { x1: p0, x2: p1, y1: 0, y2: 0 });
  svg(card.dot, { r: (p1 - p0) / 60, cx: 0, cy: 0 });
  card.dot.style.display = 'none';
  drawScale(card, q);
  const speedValue = q('.speed-value');
  const showSpeed = () => {
    speedValue.textContent = `${Math.round(Number(card.speed.value) * 100)} %`;
  };
  card.speed.addEventListener('input', showSpeed);
  showSpeed();
  const operator = me.role !== 'user';
  for (const b of node.querySelectorAll('button, input.preset-name, input.speed')) b.disabled = !operator;
  const admin = me.role === 'administrator';
  // Release (gcud's ~R) applies where this page controls the gimbal: it
  // shows there only, for an administrator (showControl).
  card.release.hidden = true;
  if (admin) {
    // ~R through gcud: refused (its words) while a higher link holds the gimbal.
    q('.release').addEventListener('click', () => {
      card.outcome.textContent = '';
      act(i, '/api/release').then((r) => {
        if (r) card.outcome.textContent = 'Released: gcud let go of this page\'s control';
      });
    });
  }
  if (operator) {
    for (const b of node.querySelectorAll('button.hold')) {
      const pan = Number(b.dataset.pan);
      const tilt = Number(b.dataset.tilt);
      b.addEventListener('pointerdown', (e) => {
        if (e.button === 0) hold(i, pan, tilt);
      });
      for (const end of ['pointerup', 'pointerleave', 'pointercancel']) b.addEventListener(end, () => release());
      b.addEventListener('keydown', (e) => {
        if ((e.key === ' ' || e.key === 'Enter') && !e.repeat) {
          e.preventDefault();
          hold(i, pan, tilt);
        }
      });
      b.addEventListener('keyup', (e) => {
        if (e.key === ' ' || e.key === 'Enter') release();
      });
    }
    node.addEventListener('keydown', (e) => {
      const dir = ARROWS[e.key];
      if (!dir || e.target.tagName === 'INPUT') return;
      e.preventDefault();
      if (!e.repeat) hold(i, dir[0], dir[1]);
    });
    node.addEventListener('keyup', (e) => {
      if (ARROWS[e.key]) release();
    });
    q('.stop').addEventListener('click', () => {
      release();
      act(i, '/api/stop');
    });
    q('.home').addEventListener('click', () => act(i, '/api/home'));
    q('.save').addEventListener('click', () => {
      const name = card.presetName.value.trim();
      if (!name) {
        showError(i, 'Type a preset name first');
        return;
      }
      act(i, '/api/preset/save', { name }).then((saved) => {
        if (saved) card.presetName.value = '';
      });
    });
    card.picture.addEventListener('click', (e) => {
      const r = card.picture.getBoundingClientRect();
      const fx = (e.clientX - r.left) / r.width;
      const fy = (e.clientY - r.top) / r.height;
      const pan = Math.round((p0 + fx * (p1 - p0)) * 100) / 100;
      const tilt = Math.round((t1 - fy * (t1 - t0)) * 100) / 100;
      act(i, '/api/goto', { pan, tilt });
    });
  }
  byId('gimbals').appendChild(node);
  return card;
}

function render(state) {
  state.gimbals.forEach((s, i) => {
    const card = cards[i];
    if (!card) return;
    card.last = s;
    clearStaleError(card);
    if (s.pan !== null && s.tilt !== null) {
      card.position.textContent = `Pan ${s.pan.toFixed(2)}° Tilt ${s.tilt.toFixed(2)}°`;
      svg(card.dot, { cx: s.pan, cy: -s.tilt });
      card.dot.style.display = '';
    }
    if (s.online) {
      card.state.textContent = `online · ${s.motion}`;
      card.state.classList.remove('offline');
    } else {
      card.state.textContent = `offline: ${s.error || 'no answer yet'}`;
      card.state.classList.add('offline');
    }
    showControl(card, s.control);
    showRules(card, s.rules);
    const shown = JSON.stringify(s.presets);
    if (shown !== card.presetsShown) {
      card.presetsShown = shown;
      card.presetList.replaceChildren();
      for (const p of s.presets) {
        const li = document.createElement('li');
        const b = document.createElement('button');
        b.type = 'button';
        b.textContent = `Go to preset ${p.name}`;
        b.disabled = me.role === 'user';
        b.addEventListener('click', () => act(i, '/api/preset/go', { n: p.n }));
        li.appendChild(b);
        card.presetList.appendChild(li);
      }
    }
  });
}

// gcud's limits (a dashed box) and keep-out zones (filled rectangles) on
// the map, in degrees; each zone carries its spans as data attributes.
function showRules(card, r) {
  const shown = JSON.stringify(r);
  if (shown === card.rulesShown) return;
  card.rulesShown = shown;
  card.zones.replaceChildren();
  card.limits.setAttribute('display', 'none');
  if (!r) {
    card.rulesText.textContent = '';
    return;
  }
  const [p0, p1] = card.g.pan_deg;
  const [t0, t1] = card.g.tilt_deg;
  const words = [];
  if (r.pan_limits || r.tilt_limits) {
    const [pl, ph] = r.pan_limits || [p0, p1];
    const [tl, th] = r.tilt_limits || [t0, t1];
    svg(card.limits, { x: pl, y: -th, width: ph - pl, height: th - tl, display: 'inline' });
    if (r.pan_limits) words.push(`pan ${pl}° to ${ph}°`);
    if (r.tilt_limits) words.push(`tilt ${tl}° to ${th}°`);
  }
  for (const z of r.keep_out) {
    const rect = document.createElementNS('http://www.w3.org/2000/svg', 'rect');
    svg(rect, {
      class: 'zone',
      x: z.pan[0],
      y: -z.tilt[1],
      width: z.pan[1] - z.pan[0],
      height: z.tilt[1] - z.tilt[0],
      'data-pan-lo': z.pan[0],
      'data-pan-hi': z.pan[1],
      'data-tilt-lo': z.tilt[0],
      'data-tilt-hi': z.tilt[1],
    });
    card.zones.appendChild(rect);
  }
  if (r.keep_out.length) words.push(`${r.keep_out.length} keep-out zone${r.keep_out.length > 1 ? 's' : ''}`);
  card.rulesText.textContent = words.length ? `gcud's rules: ${words.join(', ')}` : 'gcud sets no limits or zones';
}

// Who controls the gimbal, as gcud says (nothing while it has not said).
function showControl(card, c) {
  if (!c) {
    card.control.hidden = true;
    card.release.hidden = true;
    return;
  }
  const viewer = !me || me.role === 'user';
  let text;
  // gcud names a principal with its tool ("alice via gimbal-web"): yours
  // when it is the user signed in here; a link without principals is
  // this page's when gcud says it is the door's own.
  const yours = c.kind === 'link' && (c.via ? me && c.name === me.user : c.ours);
  if (viewer) text = c.kind === 'nobody' ? 'Nobody controls it' : `Controlled by ${c.text}`;
  else if (c.kind === 'nobody') text = 'Nobody controls it: the next command takes control';
  else if (yours && c.via) text = `Controlled by you through ${c.via} (priority ${c.priority})`;
  else if (yours) text = `Controlled through this page's gcud link: ${c.text}`;
  else if (c.kind === 'tour') text = `On gcud's ${c.text}: any operator's command takes it over`;
  else if (c.kind === 'park') text = 'Parked by gcud: any operator\'s command takes it over';
  else text = `Controlled by ${c.text}: commands from here are refused until it lets go`;
  if (viewer) text += '. You are signed in to view: your role cannot command it.';
  card.control.textContent = text;
  card.control.classList.toggle('elsewhere', c.kind === 'link' && !yours);
  card.release.hidden = !(yours && me.role === 'administrator');
  card.control.hidden = false;
}

let toursShown = '';

// gcud's tours, each with its state and (for an operator) a start or stop button.
function renderTours(tours) {
  const section = byId('tours');
  if (!tours) return;
  section.hidden = false;
  byId('tours-error').textContent = tours.error || '';
  byId('tours-none').hidden = tours.list.length > 0 || Boolean(tours.error);
  const shown = JSON.stringify(tours.list);
  if (shown === toursShown) return;
  toursShown = shown;
  const list = byId('tour-list');
  list.replaceChildren();
  for (const t of tours.list) {
    const li = document.createElement('li');
    const name = document.createElement('span');
    name.className = 'tour-name';
    name.textContent = t.name;
    const state = document.createElement('span');
    state.className = 'tour-state';
    state.textContent = t.state;
    const running = t.state !== 'stopped';
    const b = document.createElement('button');
    b.type = 'button';
    b.textContent = `${running ? 'Stop' : 'Start'} tour ${t.name}`;
    b.disabled = me.role !== 'administrator';
    b.addEventListener('click', () => {
      const outcome = byId('tour-outcome');
      api('/api/tour', { name: t.name, start: !running })
        .then((r) => {
          outcome.textContent = r.waiting_for
            ? `Tour ${t.name} waits for ${r.waiting_for} to let go of the gimbal`
            : `Tour ${t.name}: ${r.state}`;
        })
        .catch((e) => {
          outcome.textContent = e.message;
        });
    });
    li.append(name, state, b);
    list.appendChild(li);
  }
}

function listen() {
  events = new EventSource('/api/events');
  events.onopen = () => {
    byId('link').hidden = true;
  };
  events.onmessage = (e) => {
    const state = JSON.parse(e.data);
    render(state);
    renderTours(state.tours);
  };
  events.addEventListener('ended', (e) => {
    // The same user opened more pages than gimbal-web keeps live: this
    // one, the oldest, stops (reconnecting would end another of them).
    events.close();
    release();
    const link = byId('link');
    link.textContent = `Live updates stopped (${e.data}); reload the page to resume.`;
    link.hidden = false;
  });
  events.onerror = () => {
    // The connection dropped: nothing held may go on.
    release();
    const link = byId('link');
    link.textContent = 'Connection to gimbal-web lost; reconnecting…';
    link.hidden = false;
  };
}

async function load() {
  const response = await fetch('/api/session', { credentials: 'same-origin' });
  if (response.status === 401) {
    byId('sign-in').hidden = false;
    byId('who').hidden = true;
    byId('sign-out').hidden = true;
    byId('gimbals').replaceChildren();
    byId('tours').hidden = true;
    return;
  }
  me = await response.json();
  byId('sign-in').hidden = true;
  const who = byId('who');
  who.textContent = `${me.user} (${me.role}${me.role === 'user' ? ': view only' : ''})`;
  who.hidden = false;
  byId('sign-out').hidden = false;
  byId('gimbals').replaceChildren();
  toursShown = '';
  cards = me.gimbals.map(buildCard);
  listen();
}

byId('sign-in').addEventListener('submit', async (e) => {
  e.preventDefault();
  const error = byId('sign-in-error');
  error.textContent = '';
  try {
    await api('/api/sign-in', { user: byId('user').value, password: byId('password').value });
    byId('password').value = '';
    await load();
  } catch (err) {
    error.textContent = err.message;
  }
});

byId('sign-out').addEventListener('click', async () => {
  release();
  if (events) events.close();
  try {
    await api('/api/sign-out', {});
  } finally {
    me = null;
    await load();
  }
});

window.addEventListener('blur', () => release());
window.addEventListener('pagehide', () => release());
document.addEventListener('visibilitychange', () => {
  if (document.visibilityState === 'hidden') release();
});

load();
