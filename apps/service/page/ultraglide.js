// ultraglide.js: a small client of `ultraglide serve` for the browser (protocol 1, docs/service.md).
//
//   import { connect, attachPointer } from "./ultraglide.js";
//   const plate = await connect("ws://127.0.0.1:8765/ws");
//   await plate.request("view.set", { view: "main", width: 800, height: 600, units: "px",
//                                     width_mm: 211, height_mm: 159 });
//   attachPointer(canvas, plate, "main");   // touch, pen and mouse (with pressure) drive the engine
//
// request(type, fields) answers a Promise of the reply (rejected with an Error whose .code is the service's);
// post(type, fields) sends without an answer (touches); onPush(fn) receives status, output, touch.seen, scene.

export const PROTOCOL_VERSION = 1;

export class ServiceError extends Error {
  constructor(message, code) {
    super(message);
    this.code = code;
  }
}

export class Connection {
  constructor(socket) {
    this.socket = socket;
    this.nextId = 1;
    this.waiting = new Map();
    this.pushes = [];
    this.errors = [];
    this.sendTimes = []; // ms from each pointer event to its message sent (the browser's own part)
    socket.addEventListener("message", (event) => this.#receive(JSON.parse(event.data)));
    socket.addEventListener("close", () => {
      for (const [, pending] of this.waiting) pending.reject(new ServiceError("the connection was lost", "closed"));
      this.waiting.clear();
    });
  }

  #receive(message) {
    if ((message.type === "ok" || message.type === "error" || message.type === "welcome") && this.waiting.has(message.id)) {
      const pending = this.waiting.get(message.id);
      this.waiting.delete(message.id);
      if (message.type === "error") pending.reject(new ServiceError(message.message, message.code));
      else pending.resolve(message);
      return;
    }
    if (message.type === "error") {
      this.errors.push(message);
      if (this.errors.length > 100) this.errors.shift();
      return;
    }
    for (const fn of this.pushes) fn(message);
  }

  request(type, fields = {}) {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      this.socket.send(JSON.stringify({ type, id, ...fields }));
    });
  }

  post(type, fields = {}) {
    if (this.socket.readyState === WebSocket.OPEN) this.socket.send(JSON.stringify({ type, ...fields }));
  }

  onPush(fn) {
    this.pushes.push(fn);
  }

  close() {
    this.socket.close();
  }
}

// Open a connection and say hello; resolves to a Connection whose .welcome is the server's answer.
export function connect(url, role = "control", name = "browser") {
  return new Promise((resolve, reject) => {
    const socket = new WebSocket(url);
    socket.addEventListener("error", () => reject(new ServiceError(`cannot connect to ${url}`, "closed")));
    socket.addEventListener("open", async () => {
      const connection = new Connection(socket);
      try {
        connection.welcome = await connection.request("hello", { protocol: PROTOCOL_VERSION, role, client: name });
        resolve(connection);
      } catch (error) {
        reject(error);
      }
    });
  });
}

// Pointer Events on `element` drive the engine: positions in CSS px from the element's top-left corner (the
// view's units), pressure as the browser reports it, the event's own time. Returns a function that detaches.
export function attachPointer(element, connection, view) {
  const origin = performance.timeOrigin / 1000;
  const send = (event, phase) => {
    const box = element.getBoundingClientRect();
    const fields = {
      view, pointer: event.pointerId, phase,
      x: event.clientX - box.left, y: event.clientY - box.top,
      t: origin + event.timeStamp / 1000, pointer_type: event.pointerType,
    };
    if (event.pressure > 0) fields.pressure = Math.min(1, event.pressure);
    connection.post("touch", fields);
    const spent = performance.now() - event.timeStamp;
    connection.sendTimes.push(spent);
    if (connection.sendTimes.length > 10000) connection.sendTimes.shift();
  };
  const handlers = {
    pointerdown: (event) => {
      element.setPointerCapture?.(event.pointerId);
      send(event, "down");
      event.preventDefault();
    },
    pointermove: (event) => {
      if (event.buttons === 0 && event.pointerType === "mouse") return; // a mouse hovering: no finger
      if (event.pointerType !== "mouse" && event.pressure === 0 && event.buttons === 0) return; // a pen hovering
      const coalesced = event.getCoalescedEvents ? event.getCoalescedEvents() : [];
      for (const each of coalesced.length ? coalesced : [event]) send(each, "move");
      event.preventDefault();
    },
    pointerup: (event) => send(event, "up"),
    pointercancel: (event) => send(event, "cancel"),
  };
  for (const [name, handler] of Object.entries(handlers)) element.addEventListener(name, handler);
  element.style.touchAction = "none"; // the browser must not scroll or zoom under the finger
  return () => {
    for (const [name, handler] of Object.entries(handlers)) element.removeEventListener(name, handler);
  };
}

// A File or Blob (a PNG) as the base64 a texture.load message carries.
export async function fileToBase64(file) {
  const bytes = new Uint8Array(await file.arrayBuffer());
  let text = "";
  for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(text);
}
