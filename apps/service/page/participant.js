// The participant's page (`ultraglide experiment run DESIGN.toml --serve`): each trial's zones drawn at their size
// in mm, touches on them sent as the service's touch messages (mm from the trial's area's top-left corner), the
// question with the design's labels as buttons (a number field for magnitude estimation; −, + and a slider for the
// method of adjustment, whose every level the plate plays before the page is told), breaks with a button.
// Keys answer as at the window (apps/experiment/window.py, design_window.py); Esc stops the session as the window's
// does (participant.stop); the hint line under the buttons says which. Every word on the page that is not a block's
// question or labels comes with the screen, in the design's words (its [words], English by default). The reaction
// time runs from the frame that presents the trial (performance.now()) to the answer.
// ?mm_per_px=N gives the screen's pitch (default: CSS's 96 px per inch, 0.2646 mm); ?token=... as printed.
import { connect } from "./ultraglide.js";

const query = new URLSearchParams(location.search);
const token = query.get("token");
const mmPerPx = Number(query.get("mm_per_px")) || 25.4 / 96;
const suffix = token ? `?token=${encodeURIComponent(token)}` : "";
const $ = (id) => document.getElementById(id);
const plate = $("plate"), answers = $("answers"), note = $("note");

const state = { ready: false, ended: false, screen: null, shownAt: null, errors: [], presented: 0, answered: [],
                level: null, applied: null, stopped: null };
const adjusting = { sending: null, idle: [] }; // the adjust request in flight; who waits for the last to play
window.participant = state;
let connection = null;
let pointer = null; // the pointer that drives: {id, inside}

function clear() {
  plate.replaceChildren();
  answers.replaceChildren();
  answers.style.pointerEvents = "";
  plate.style.width = plate.style.height = "0px";
  $("question").textContent = "";
  $("progress").textContent = "";
  $("keys").textContent = "";
}

function button(label, onPress) { // pressed as the window's are: at the finger's (or the mouse button's) down
  const element = document.createElement("button");
  element.textContent = label;
  element.tabIndex = -1; // never focused: Enter and space are the page's keys, not a focused button's
  element.addEventListener("pointerdown", (event) => { // a second finger too (a finger held on a zone makes
    if (event.button !== 0 || element.disabled) return; // the browser's click a two-finger gesture: none)
    event.preventDefault();
    onPress();
  });
  return element;
}

// ---- the method of adjustment: the level the page sets, sent one request at a time (the latest wins) --------------
const clampLevel = (screen, level) => Math.min(Math.max(level, screen.range[0]), screen.range[1]);
const sliderDb = (screen, level) => 20 * Math.log10(level / screen.range[0]);
const THUMB_PX = 48; // the slider's thumb, as wide as a fingertip

function placeThumb(screen) {
  const slider = $("level");
  if (!slider) return;
  const fraction = sliderDb(screen, state.level) / sliderDb(screen, screen.range[1]);
  slider.querySelector(".thumb").style.left = `calc(${fraction} * (100% - ${THUMB_PX}px))`;
}

function setLevel(screen, level) {
  if (state.screen !== screen || state.shownAt === null) return;
  state.level = clampLevel(screen, level);
  placeThumb(screen);
  if (!adjusting.sending) sendLevel(screen);
}

function step(screen, direction) { // the window's: one step_db up or down, within the range
  if (state.level !== null) setLevel(screen, state.level * 10 ** (direction * screen.step_db / 20));
}

async function sendLevel(screen) {
  while (state.screen === screen && state.level !== state.applied) {
    const level = state.level;
    adjusting.sending = connection.request("participant.adjust", { trial: screen.trial, level });
    try {
      const reply = await adjusting.sending;
      if (state.screen === screen) state.applied = reply.level;
    } catch (error) {
      if (state.screen === screen) { // refused while the trial goes on (not a trial ended meanwhile: Esc)
        state.errors.push(error.message);
        note.textContent = error.message;
      }
      break;
    } finally {
      adjusting.sending = null;
    }
  }
  for (const resolve of adjusting.idle.splice(0)) resolve();
}

async function settled() { // the last level set, played
  if (adjusting.sending) await new Promise((resolve) => adjusting.idle.push(resolve));
}

function showAdjustment(screen) {
  state.level = state.applied = screen.level; // the plate plays it already (a reconnected page: the level set last)
  const [down, up, ok] = screen.labels;
  // the slider: the level in dB above the range's low end, left to right; dragged by pointer events (a second
  // finger while one rests on a zone, which a native range input would take for a two-finger gesture)
  const slider = document.createElement("div");
  slider.id = "level";
  slider.className = "slider";
  const track = document.createElement("div");
  track.className = "track";
  const thumb = document.createElement("div");
  thumb.className = "thumb";
  slider.append(track, thumb);
  let dragging = null;
  const follow = (event) => {
    const box = slider.getBoundingClientRect();
    const fraction = Math.min(Math.max((event.clientX - box.left - THUMB_PX / 2) / (box.width - THUMB_PX), 0), 1);
    setLevel(screen, screen.range[0] * 10 ** (fraction * sliderDb(screen, screen.range[1]) / 20));
  };
  slider.addEventListener("pointerdown", (event) => {
    if (dragging !== null || event.button !== 0) return;
    event.preventDefault();
    dragging = event.pointerId;
    slider.setPointerCapture?.(event.pointerId);
    follow(event);
  });
  slider.addEventListener("pointermove", (event) => { if (event.pointerId === dragging) follow(event); });
  for (const kind of ["pointerup", "pointercancel"]) {
    slider.addEventListener(kind, (event) => { if (event.pointerId === dragging) dragging = null; });
  }
  const go = async () => {
    if (state.screen !== screen || state.shownAt === null) return;
    await settled();
    answer(screen, { value: state.level });
  };
  answers.style.position = "static";
  answers.style.width = answers.style.height = "";
  const row = document.createElement("div");
  row.className = "adjust";
  row.append(button(down, () => step(screen, -1)), slider, button(up, () => step(screen, +1)));
  const confirm = button(ok, go);
  confirm.id = "confirm";
  answers.append(row, confirm);
  screen.confirm = go;
  placeThumb(screen);
}

function showTrial(screen) {
  $("pause").style.display = "none";
  $("screen").style.display = "flex";
  clear();
  $("progress").textContent = screen.progress;
  $("question").textContent = screen.question;
  const px = (mm) => `${mm / mmPerPx}px`;
  plate.style.width = px(screen.size_mm[0]);
  plate.style.height = px(screen.size_mm[1]);
  screen.zones.forEach((zone, index) => {
    const element = document.createElement("div");
    element.className = "zone";
    Object.assign(element.style, { left: px(zone.x_mm), top: px(zone.y_mm), width: px(zone.width_mm),
                                   height: px(zone.height_mm) });
    if (screen.numbered) element.textContent = String(index + 1);
    plate.append(element);
  });
  const send = (fields) => answer(screen, fields);
  $("keys").textContent = screen.keys; // the hint line, in the design's words
  if (screen.mode === "adjustment") {
    showAdjustment(screen);
  } else if (screen.mode === "magnitude") {
    const field = document.createElement("input");
    field.type = "text";
    field.inputMode = "decimal";
    field.autocomplete = "off";
    field.id = "estimate";
    const go = () => {
      const value = Number(field.value.replace(",", "."));
      if (field.value.trim() === "" || !Number.isFinite(value) || value < 0) {
        field.select();
        return;
      }
      send({ value });
    };
    field.addEventListener("keydown", (event) => {
      if (event.key === "Enter") go();
      if (event.key !== "Escape") event.stopPropagation(); // typed into the field itself, not the page's keys
    });
    answers.style.position = "static";
    answers.style.width = answers.style.height = "";
    answers.append(field, button(screen.ok, go));
    screen.confirm = go;
  } else if (screen.mode === "choice") { // a button under each zone
    answers.style.position = "relative";
    answers.style.width = plate.style.width;
    answers.style.height = "64px";
    screen.labels.forEach((label, index) => {
      const zone = screen.zones[index];
      const element = button(label, () => send({ button: index }));
      element.style.position = "absolute";
      element.style.left = `calc(${px(zone.x_mm + zone.width_mm / 2)} - 55px)`;
      answers.append(element);
    });
  } else {
    answers.style.position = "static";
    answers.style.width = answers.style.height = "";
    screen.labels.forEach((label, index) => answers.append(button(label, () => send({ button: index }))));
  }
  state.shownAt = null;
  requestAnimationFrame(() => { state.shownAt = performance.now(); state.presented += 1; });
}

async function answer(screen, fields) {
  if (state.screen !== screen || state.shownAt === null) return; // answered already, or not yet drawn
  const rt_s = (performance.now() - state.shownAt) / 1000;
  state.screen = null;
  for (const element of answers.querySelectorAll("button, input")) element.disabled = true;
  answers.style.pointerEvents = "none"; // the slider too, till the next screen
  document.activeElement?.blur?.();
  lift(performance.now());
  try {
    await connection.request("participant.answer", { trial: screen.trial, rt_s, ...fields });
    state.answered.push({ trial: screen.trial, rt_s, ...fields });
  } catch (error) {
    state.errors.push(error.message);
    note.textContent = error.message;
  }
}

function showBreak(screen) {
  $("screen").style.display = "none";
  $("pause").style.display = "flex";
  $("breakMessage").textContent = screen.message;
  $("breakKeys").textContent = screen.keys;
  const go = $("breakButton");
  go.textContent = screen.label;
  go.disabled = false;
  go.onclick = async () => {
    go.disabled = true;
    try {
      await connection.request("participant.continue", { trial: screen.trial });
    } catch (error) {
      state.errors.push(error.message);
    }
  };
}

// ---- keys: as the window's (window.py, design_window.py) --------------------------------------------------------
function keyAnswer(screen, key) { // what the key does on this trial's screen: true if it did something
  const n = screen.labels.length;
  const digit = /^[1-9]$/.test(key) ? Number(key) : null;
  const press = (index) => { answer(screen, { button: index }); return true; };
  switch (screen.mode) {
    case "choice":
      if (digit !== null && digit <= n) return press(digit - 1);
      if (key === "ArrowLeft") return press(0);
      if (key === "ArrowRight") return press(n - 1);
      return false;
    case "yes_no": // Yes is the first button
      if (key === "y" || key === "Y") return press(0);
      if (key === "n" || key === "N") return press(1);
      return false;
    case "pair":
      if (key === "s" || key === "S") return press(0);
      if (key === "d" || key === "D") return press(1);
      return false;
    case "rating":
      return digit !== null && digit <= n ? press(digit - 1) : false;
    case "adjustment":
      if (key === "ArrowLeft" || key === "-") { step(screen, -1); return true; }
      if (key === "ArrowRight" || key === "+" || key === "=") { step(screen, +1); return true; }
      if (key === "Enter") { screen.confirm(); return true; }
      return false;
    case "magnitude": { // typed into the number field wherever the focus is
      const field = $("estimate");
      if (key === "Enter") { screen.confirm(); return true; }
      if (key === "Backspace") { field.value = field.value.slice(0, -1); return true; }
      if (/^[0-9.,]$/.test(key) && field.value.length < 12) { field.value += key; return true; }
      return false;
    }
    default:
      return false;
  }
}

// Esc: the session stops, as at the window (its files complete, status "stopped"; --resume continues it)
async function stopSession(screen) {
  if (state.screen !== screen) return;
  state.screen = null;
  for (const element of document.querySelectorAll("#answers button, #answers input, #breakButton")) {
    element.disabled = true;
  }
  answers.style.pointerEvents = "none";
  lift(performance.now());
  try {
    await connection.request("participant.stop", { trial: screen.trial });
    state.stopped = screen.trial;
  } catch (error) {
    state.errors.push(error.message);
    note.textContent = error.message;
  }
}

addEventListener("keydown", (event) => {
  const screen = state.screen;
  if (!screen || event.repeat || event.ctrlKey || event.metaKey || event.altKey) return;
  if (event.key === "Escape" && (screen.type === "participant.break" || state.shownAt !== null)) {
    event.preventDefault();
    stopSession(screen);
  } else if (screen.type === "participant.break") { // a break's button by the keyboard too (space or Enter)
    if (event.key === " " || event.key === "Enter") {
      event.preventDefault();
      $("breakButton").click();
    }
  } else if (screen.type === "participant.trial" && state.shownAt !== null && keyAnswer(screen, event.key)) {
    event.preventDefault();
  }
});

function showWait() {
  $("pause").style.display = "none";
  $("screen").style.display = "flex";
  clear();
}

// ---- touches: pointer events on the trial's area, in mm ----------------------------------------------------
const origin = performance.timeOrigin / 1000;
function post(event, phase) {
  const box = plate.getBoundingClientRect();
  const fields = { view: "main", pointer: event.pointerId, phase, x: (event.clientX - box.left) * mmPerPx,
                   y: (event.clientY - box.top) * mmPerPx, t: origin + event.timeStamp / 1000,
                   pointer_type: event.pointerType };
  if (event.pressure > 0) fields.pressure = Math.min(1, event.pressure);
  connection?.post("touch", fields);
}

function inside(event) {
  const box = plate.getBoundingClientRect();
  return event.clientX >= box.left && event.clientX < box.right && event.clientY >= box.top &&
         event.clientY < box.bottom;
}

function lift(now) {
  if (pointer && pointer.inside) {
    connection?.post("touch", { view: "main", pointer: pointer.id, phase: "up", x: 0, y: 0,
                                t: origin + now / 1000 });
  }
  pointer = null;
}

plate.addEventListener("pointerdown", (event) => {
  event.preventDefault();
  if (!state.screen || state.screen.type !== "participant.trial" || pointer) return;
  plate.setPointerCapture?.(event.pointerId);
  pointer = { id: event.pointerId, inside: true };
  post(event, "down");
});
plate.addEventListener("pointermove", (event) => {
  if (!pointer || event.pointerId !== pointer.id) return;
  event.preventDefault();
  const coalesced = event.getCoalescedEvents ? event.getCoalescedEvents() : [];
  for (const each of coalesced.length ? coalesced : [event]) {
    const now = inside(each);
    if (now) post(each, pointer.inside ? "move" : "down"); // off the area the finger is lifted; back, down again
    else if (pointer.inside) post(each, "up");
    pointer.inside = now;
  }
});
for (const kind of ["pointerup", "pointercancel"]) {
  plate.addEventListener(kind, (event) => {
    if (!pointer || event.pointerId !== pointer.id) return;
    if (pointer.inside) post(event, kind === "pointerup" ? "up" : "cancel");
    pointer = null;
  });
}

// ---- the connection: kept, and made again when it is lost ---------------------------------------------------
let lostWords = "connection lost; trying again"; // the design's words for it once a screen has brought them
function onPush(message) {
  if (message.language) document.documentElement.lang = message.language; // the design's: the page's language
  if (message.connection_lost) lostWords = message.connection_lost;
  if (message.type === "participant.trial") {
    state.screen = message;
    showTrial(message);
  } else if (message.type === "participant.break") {
    state.screen = message;
    showBreak(message);
  } else if (message.type === "participant.wait") {
    state.screen = null;
    showWait();
  } else if (message.type === "participant.end") { // the session is over: no trial, no reconnecting
    state.screen = null;
    state.ended = true;
    showWait();
    $("question").textContent = message.message;
  }
}

async function open() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  for (;;) {
    try {
      connection = await connect(`${scheme}://${location.host}/ws${suffix}`, "control", "participant");
      break;
    } catch (error) {
      note.textContent = `not connected (${error.message}); trying again`;
      await new Promise((resolve) => setTimeout(resolve, 1000));
    }
  }
  note.textContent = "";
  connection.onPush(onPush);
  connection.socket.addEventListener("close", () => {
    state.ready = false;
    pointer = null;
    if (state.ended) {
      note.textContent = "";
      return;
    }
    note.textContent = lostWords;
    setTimeout(open, 1000);
  });
  state.ready = true;
}

open();
