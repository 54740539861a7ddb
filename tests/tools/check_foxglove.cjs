// tests/tools/check_foxglove.cjs -- connects to a running view with
// @foxglove/ws-protocol's client, an independent one, and checks what it
// says. Two clients: one reads everything; one subscribes to /mesh and then
// stops reading (its socket paused). The first must keep getting new ticks
// while the second is stalled, and the server must drop the second.
//   node check_foxglove.cjs NODE_MODULES URL NT TOPIC...
// (TOPIC...: the channels an MCAP export of the same session has.)
"use strict";
const path = require("path");
const net = require("net");
const fs = require("fs");
const [modules, url, ntS, ...topics] = process.argv.slice(2);
const { FoxgloveClient } = require(path.join(modules, "@foxglove/ws-protocol"));
const WebSocket = require(path.join(modules, "ws"));
const nt = Number(ntS);

function fail(msg) {
  console.log("FAIL " + msg);
  process.exit(1);
}
function ok(msg) {
  console.log("ok   " + msg);
}
setTimeout(() => fail("timed out"), 110000);

function connect() {
  const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  return { ws, client: new FoxgloveClient({ ws }) };
}

const reader = connect();
let channels = null, serverInfo = null, ticks = [], meshes = 0;
let stalledAt = 0, ticksAfterStall = 0, stallerClosed = false, staller = null;

reader.client.on("serverInfo", (i) => (serverInfo = i));
reader.client.on("advertise", (chs) => {
  channels = chs;
  const got = chs.map((c) => c.topic).sort().join(" ");
  const want = [...topics].sort().join(" ");
  if (got !== want) fail(`advertised ${got}, the MCAP export has ${want}`);
  for (const c of chs)
    if (c.encoding !== "json" || c.schemaEncoding !== "jsonschema" || !JSON.parse(c.schema))
      fail("channel " + c.topic + " is not json with a jsonschema");
  ok(`serverInfo ${serverInfo && serverInfo.name}; advertised the export's ${chs.length} channels`);
  for (const c of chs) reader.client.subscribe(c.id);
  stall(chs.find((c) => c.topic === "/mesh").id);
});
reader.client.on("message", ({ timestamp, data }) => {
  const j = JSON.parse(Buffer.from(data.buffer, data.byteOffset, data.byteLength).toString("utf8"));
  if (j.tick !== undefined) {
    ticks.push(j.tick);
    if (stalledAt) ticksAfterStall++;
  }
  if (j.entities) {
    meshes++;
    let tri = 0;
    for (const t of j.entities[0].triangles) tri += t.indices.length / 3;
    if (tri !== nt) fail(`a mesh of ${tri} triangles, want ${nt}`);
    const e = j.entities[0].timestamp;
    if (BigInt(e.sec) * 1000000000n + BigInt(e.nsec) !== timestamp)
      fail("message time is not the entity's stream time");
  }
  check();
});

// A client that subscribes to /mesh and then never reads: a raw socket,
// paused from the start, so the server's batches pile up unread.
function stall(meshId) {
  const u = new URL(url);
  const s = net.connect(Number(u.port), u.hostname, () => {
    s.pause();
    s.write(
      `GET ${u.pathname} HTTP/1.1\r\nHost: ${u.host}\r\nUpgrade: websocket\r\n` +
        `Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n` +
        `Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n`
    );
    const msg = Buffer.from(JSON.stringify({ op: "subscribe", subscriptions: [{ id: 7, channelId: meshId }] }));
    const mask = Buffer.from([1, 2, 3, 4]);
    const head = msg.length < 126 ? Buffer.from([0x81, 0x80 | msg.length]) : Buffer.from([0x81, 0x80 | 126, msg.length >> 8, msg.length & 255]);
    s.write(Buffer.concat([head, mask, Buffer.from(msg.map((b, i) => b ^ mask[i % 4]))]));
    stalledAt = Date.now();
    const row = serverEnd();
    if (!row || row[3] !== "01") fail("the stalled client's connection is not in /proc/net/tcp");
  });
  s.on("close", () => (stallerClosed = true));
  s.on("error", () => (stallerClosed = true));
  staller = s;
}

// The server's end of the stalled client's connection in /proc/net/tcp
// (fields: sl, local, remote, state; 01 is ESTABLISHED), or undefined.
function serverEnd() {
  const port = Number(new URL(url).port), mine = staller.localPort;
  const hex = (n) => n.toString(16).toUpperCase().padStart(4, "0");
  const rows = fs.readFileSync("/proc/net/tcp", "utf8").split("\n").slice(1);
  return rows.map((r) => r.trim().split(/\s+/)).find(
    (f) => f.length > 3 && f[1].endsWith(":" + hex(port)) && f[2].endsWith(":" + hex(mine)));
}

let waiting = false;
function check() {
  if (waiting || ticksAfterStall < 20 || meshes < 10) return;
  waiting = true;
  ok(`reader: ${ticks.length} ticks, ${meshes} meshes of ${nt} triangles; ${ticksAfterStall} ticks since the other client stopped reading`);
  for (let i = 1; i < ticks.length; i++) if (ticks[i] <= ticks[i - 1]) fail("ticks out of order");
  ok("ticks in order (latest wins: ticks in between may be skipped)");
  // Its socket buffers fill within a few seconds (the kernel does not grow
  // a receive buffer nobody reads), then its batch waits past the server's
  // 2 s limit and the server closes it. The client, still not reading, cannot
  // see the close (the FIN waits behind the unread data), so look at the
  // server's end in the kernel's table: it leaves ESTABLISHED.
  const t0 = Date.now();
  const poll = setInterval(() => {
    const row = serverEnd();
    if (!row || row[3] !== "01") {
      ok(`the client that stopped reading was disconnected ${((Date.now() - stalledAt) / 1000).toFixed(1)} s after it stopped, and the reader was not held up`);
      process.exit(0);
    }
    if (Date.now() - t0 > 40000) fail("the client that stopped reading is still connected after 40 s");
  }, 100);
}
