// The page `ultraglide serve --page` serves: the whole window is the view "main"; the sprites are drawn where
// they are felt; touch, pen and mouse drive the engine; a texture (PNG) dropped on the page becomes a sprite.
// ?mm_per_px=N gives the screen's pitch (default: CSS's 96 px per inch, 0.2646 mm); ?token=... as printed.
import { attachPointer, connect, fileToBase64 } from "./ultraglide.js";

const query = new URLSearchParams(location.search);
const token = query.get("token");
const mmPerPx = Number(query.get("mm_per_px")) || 25.4 / 96;
const suffix = token ? `?token=${encodeURIComponent(token)}` : "";
const canvas = document.getElementById("view");
const statusLine = document.getElementById("status");
const images = new Map(); // texture id -> HTMLImageElement of its friction map
let scene = { views: [], sprites: [], textures: [] };
let words = "";
let dropped = 0;

window.ultraglide = { ready: false, scene: () => scene, sendTimes: () => connection?.sendTimes ?? [], errors: [] };
let connection = null;

function imageOf(textureId) {
  if (!images.has(textureId)) {
    const image = new Image();
    image.onload = draw;
    image.src = `/texture/${encodeURIComponent(textureId)}.png${suffix}`;
    images.set(textureId, image);
  }
  return images.get(textureId);
}

function draw() {
  const context = canvas.getContext("2d");
  context.setTransform(devicePixelRatio, 0, 0, devicePixelRatio, 0, 0);
  const view = scene.views.find((v) => v.view === "main");
  context.fillStyle = "#fff";
  context.fillRect(0, 0, canvas.clientWidth, canvas.clientHeight);
  if (view) {
    const shade = Math.round(255 * view.background_ratio);
    context.fillStyle = `rgb(${shade},${shade},${shade})`;
    context.fillRect(0, 0, view.width, view.height);
  }
  const shown = scene.sprites.filter((s) => s.view === "main" && s.visible);
  shown.forEach((s, i) => { s._i = i; });
  shown.sort((a, b) => a.z - b.z || a._i - b._i);
  for (const sprite of shown) {
    context.save();
    context.translate(sprite.x + sprite.width / 2, sprite.y + sprite.height / 2);
    context.rotate((sprite.rotation_deg * Math.PI) / 180);
    const image = imageOf(sprite.texture);
    if (image.complete && image.naturalWidth) {
      context.drawImage(image, -sprite.width / 2, -sprite.height / 2, sprite.width, sprite.height);
    } else {
      context.fillStyle = "#bbb";
      context.fillRect(-sprite.width / 2, -sprite.height / 2, sprite.width, sprite.height);
    }
    context.strokeStyle = "#37a";
    context.strokeRect(-sprite.width / 2, -sprite.height / 2, sprite.width, sprite.height);
    context.restore();
  }
  statusLine.textContent = words + (dropped ? `\n${dropped} texture(s) placed from files` : "");
}

async function fitView() {
  canvas.width = Math.round(canvas.clientWidth * devicePixelRatio);
  canvas.height = Math.round(canvas.clientHeight * devicePixelRatio);
  const width = canvas.clientWidth, height = canvas.clientHeight;
  await connection.request("view.set", { view: "main", width, height, units: "px",
                                         width_mm: width * mmPerPx, height_mm: height * mmPerPx });
  scene = await connection.request("state");
  draw();
}

async function main() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  try {
    connection = await connect(`${scheme}://${location.host}/ws${suffix}`, "control", "page");
  } catch (error) {
    try {
      connection = await connect(`${scheme}://${location.host}/ws${suffix}`, "observe", "page");
      words = "observing: another client controls the plate";
    } catch (second) {
      statusLine.textContent = `not connected: ${second.message}`;
      return;
    }
  }
  connection.onPush((message) => {
    if (message.type === "scene") {
      scene = message;
      draw();
    } else if (message.type === "status") {
      words = `${message.device} ${message.state} · limit ${message.limit_um_pp} µm p-p · ` +
              `${message.limited_percent.toFixed(0)} % at the limit` +
              (message.faults.length ? ` · faults: ${message.faults.join(", ")}` : "") +
              (message.role === "observe" ? " · observing" : "");
      draw();
    }
  });
  await connection.request("subscribe", { status: 2, scene: true });
  if (connection.welcome.role === "control") {
    await fitView();
    attachPointer(canvas, connection, "main");
    addEventListener("resize", () => fitView().catch((e) => window.ultraglide.errors.push(e.message)));
  } else {
    scene = await connection.request("state");
    draw();
  }
  window.ultraglide.ready = true;
}

addEventListener("dragover", (event) => { event.preventDefault(); document.body.classList.add("dragging"); });
addEventListener("dragleave", () => document.body.classList.remove("dragging"));
addEventListener("drop", async (event) => {
  event.preventDefault();
  document.body.classList.remove("dragging");
  const file = event.dataTransfer?.files?.[0];
  if (!file || !connection) return;
  try {
    const id = `drop${++dropped}`;
    const texture = await connection.request("texture.load", { texture: id, png: await fileToBase64(file),
                                                               name: file.name.replace(/\.[^.]*$/, "") });
    const width = texture.width_mm / mmPerPx, height = texture.height_mm / mmPerPx;
    await connection.request("sprite.set", { sprite: id, texture: id, view: "main", x: event.clientX - width / 2,
                                             y: event.clientY - height / 2, width, height, z: 1000 + dropped });
  } catch (error) {
    words = `that file was refused: ${error.message}`;
    window.ultraglide.errors.push(error.message);
    draw();
  }
});

main();
