// tests/tools/check_mcap.cjs -- reads an MCAP file with @mcap/core, an
// independent reader, and checks it against what the test says it holds.
//   node check_mcap.cjs NODE_MODULES FILE PLAIN COMPRESSION TICKS NV NT HANDLE R00 R01 ... R22
// FILE's chunks are to be compressed with COMPRESSION ("zstd", or "" for
// none); they are decompressed by fzstd, a zstd decoder of its own (not
// libzstd), and every message must be the one PLAIN, the same recording
// exported without compression, holds. Prints one line per check and
// exits 1 on the first failure.
"use strict";
const path = require("path");
const fs = require("fs");
const zlib = require("zlib");
const [modules, file, plain, compression, ticksS, nvS, ntS, handle, ...Rs] = process.argv.slice(2);
const { McapIndexedReader, McapStreamReader } = require(path.join(modules, "@mcap/core"));
const fzstd = require(path.join(modules, "fzstd"));
const ticks = Number(ticksS), nv = Number(nvS), nt = Number(ntS), R = Rs.map(Number);
// what @mcap/core calls for a chunk's records; it checks the CRC itself
const decompressHandlers = {
  zstd: (data, size) => {
    const out = fzstd.decompress(data);
    if (BigInt(out.length) !== size) fail(`a chunk decompresses to ${out.length} bytes, not ${size}`);
    return out;
  },
};

function fail(msg) {
  console.log("FAIL " + msg);
  process.exit(1);
}
function ok(msg) {
  console.log("ok   " + msg);
}

function crc32(buf) {
  if (zlib.crc32) return zlib.crc32(buf) >>> 0;
  let c = ~0;
  for (const b of buf) {
    c ^= b;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  }
  return ~c >>> 0;
}

// The quaternion of a row-major rotation, computed here on its own.
function quat(m) {
  const w = Math.sqrt(Math.max(0, 1 + m[0] + m[4] + m[8])) / 2;
  let x = Math.sqrt(Math.max(0, 1 + m[0] - m[4] - m[8])) / 2;
  let y = Math.sqrt(Math.max(0, 1 - m[0] + m[4] - m[8])) / 2;
  let z = Math.sqrt(Math.max(0, 1 - m[0] - m[4] + m[8])) / 2;
  x = Math.sign(m[7] - m[5]) * x;
  y = Math.sign(m[2] - m[6]) * y;
  z = Math.sign(m[3] - m[1]) * z;
  return [x, y, z, w];
}

async function main() {
  const buf = fs.readFileSync(file);
  // The data section's CRC: every byte before the Data End record. On the
  // way, every chunk on its own: its compression as asked, its records
  // decompressed to its uncompressed size, and its uncompressed CRC (the
  // spec's: of the records after decompression) theirs.
  let off = 8;
  const chunks = new Map(); // offset -> {compression, compressedSize, uncompressedSize}
  let packed = 0, unpacked = 0;
  for (;;) {
    const op = buf[off];
    const len = Number(buf.readBigUInt64LE(off + 1));
    if (op === 0x0f) {
      const want = buf.readUInt32LE(off + 9);
      if (want !== crc32(buf.subarray(0, off))) fail("data section CRC");
      ok("data section CRC " + want.toString(16));
      break;
    }
    if (op === 0x06) {
      let p = off + 9 + 16;
      const size = buf.readBigUInt64LE(p), crc = buf.readUInt32LE(p + 8);
      const nameLen = buf.readUInt32LE(p + 12);
      const name = buf.subarray(p + 16, p + 16 + nameLen).toString("utf8");
      p += 16 + nameLen;
      const n = Number(buf.readBigUInt64LE(p));
      if (p + 8 + n !== off + 9 + len) fail(`chunk at ${off}: its records do not end the record`);
      const records = buf.subarray(p + 8, p + 8 + n);
      if (name !== compression) fail(`chunk at ${off} compressed "${name}", want "${compression}"`);
      const data = name === "zstd" ? fzstd.decompress(records) : records;
      if (BigInt(data.length) !== size) fail(`chunk at ${off}: ${data.length} bytes, not ${size}`);
      if (crc32(data) !== crc) fail(`chunk at ${off}: uncompressed CRC`);
      chunks.set(BigInt(off), { compression: name, compressedSize: BigInt(n), uncompressedSize: size });
      packed += n;
      unpacked += data.length;
    }
    off += 9 + len;
    if (off >= buf.length) fail("no Data End record");
  }
  ok(`${chunks.size} chunks "${compression}": ${unpacked} bytes of records in ${packed}, ` +
     "each of its uncompressed size and CRC");
  const readable = {
    size: async () => BigInt(buf.length),
    read: async (o, n) => buf.subarray(Number(o), Number(o + n)),
  };
  // checks the summary CRC
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  ok("indexed reader: footer, summary CRC " + reader.footer.summaryCrc.toString(16));
  if (reader.footer.summaryCrc === 0) fail("summary CRC not filled");
  if (reader.chunkIndexes.length === 0) fail("no chunk index");
  if (reader.chunkIndexes.length !== chunks.size) fail("a chunk index a chunk");
  for (const ci of reader.chunkIndexes) {
    const c = chunks.get(ci.chunkStartOffset);
    if (!c) fail(`chunk index at ${ci.chunkStartOffset}: no chunk there`);
    for (const k of ["compression", "compressedSize", "uncompressedSize"])
      if (ci[k] !== c[k]) fail(`chunk index at ${ci.chunkStartOffset}: ${k} ${ci[k]}, the chunk's ${c[k]}`);
  }
  ok("chunk indexes: each chunk's offset, compression and sizes");
  const topics = new Map([...reader.channelsById].map(([id, c]) => [id, c.topic]));
  const count = new Map();
  let last = -1n, n = 0, lastCmd = null, loops = [], meshes = 0;
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    if (m.logTime < last) fail("messages out of order");
    last = m.logTime;
    n++;
    const topic = topics.get(m.channelId);
    count.set(topic, (count.get(topic) || 0) + 1);
    const j = JSON.parse(Buffer.from(m.data).toString("utf8"));
    if (topic === "/loop") loops.push(j);
    if (topic === `/handles/${handle}/commanded`) lastCmd = j;
    if (topic === "/mesh") {
      meshes++;
      const e = j.entities[0];
      let tri = 0;
      for (const t of e.triangles) {
        tri += t.indices.length / 3;
        for (const i of t.indices) if (i >= t.points.length) fail("index past its points");
      }
      if (tri !== nt) fail(`mesh message with ${tri} triangles, the mesh has ${nt}`);
      if (BigInt(e.timestamp.sec) * 1000000000n + BigInt(e.timestamp.nsec) !== m.logTime)
        fail("mesh timestamp is not the log time");
    }
  }
  ok(`${n} messages, chunk CRCs checked, every one valid JSON`);
  const st = reader.statistics;
  if (!st || Number(st.messageCount) !== n) fail("statistics message count");
  if (st.chunkCount !== reader.chunkIndexes.length) fail("statistics chunk count");
  for (const [id, c] of st.channelMessageCounts)
    if (Number(c) !== count.get(topics.get(id))) fail("per-channel count of " + topics.get(id));
  ok("statistics agree: " + [...count].map(([t, c]) => `${t} ${c}`).join(", "));
  if (meshes !== ticks || loops.length !== ticks) fail(`${meshes} meshes, ${loops.length} ticks, want ${ticks}`);
  if (loops[ticks - 1].tick !== ticks - 1) fail("last tick number");
  if ("tick_ms" in loops[0]) fail("an export carries wall-clock figures");
  const q = quat(R), g = lastCmd.rotation;
  const d = Math.max(...[g.x - q[0], g.y - q[1], g.z - q[2], g.w - q[3]].map(Math.abs));
  if (!(d < 1e-9)) fail(`last commanded rotation differs from the replay's by ${d}`);
  ok(`one mesh and one /loop a tick (${ticks}); last commanded rotation matches the replay (${d.toExponential(1)})`);
  // seeking: messages from the middle on, through the chunk index
  const mid = reader.statistics.messageStartTime + (reader.statistics.messageEndTime - reader.statistics.messageStartTime) / 2n;
  let after = 0, early = 0;
  for await (const m of reader.readMessages({ startTime: mid })) {
    after++;
    if (m.logTime < mid) early++;
  }
  if (after === 0 || after >= n || early) fail(`seek to the middle gave ${after} messages (${early} early)`);
  ok(`seek to the middle: ${after} of ${n} messages`);
  // a streaming reader over the whole file
  const sr = new McapStreamReader({ validateCrcs: true, decompressHandlers });
  sr.append(buf);
  let rec, smsg = 0, sawFooter = false;
  while ((rec = sr.nextRecord())) {
    if (rec.type === "Message") smsg++;
    if (rec.type === "Footer") sawFooter = true;
  }
  if (!sr.done() || !sawFooter || smsg !== n) fail("stream reader");
  ok("stream reader: the same messages, through to the footer");
  // every message against the uncompressed export of the same recording
  const pbuf = fs.readFileSync(plain);
  const preader = await McapIndexedReader.Initialize({
    readable: {
      size: async () => BigInt(pbuf.length),
      read: async (o, k) => pbuf.subarray(Number(o), Number(o + k)),
    },
  });
  const ptopics = new Map([...preader.channelsById].map(([id, c]) => [id, c.topic]));
  const mine = reader.readMessages(), theirs = preader.readMessages();
  let same = 0;
  for (;;) {
    const [a, b] = [await mine.next(), await theirs.next()];
    if (a.done || b.done) {
      if (a.done !== b.done) fail(`${same} messages alike, then one file ends first`);
      break;
    }
    const x = a.value, y = b.value;
    const what = `message ${same} (${topics.get(x.channelId)})`;
    if (topics.get(x.channelId) !== ptopics.get(y.channelId)) fail(`${what}: another topic`);
    if (x.sequence !== y.sequence || x.logTime !== y.logTime || x.publishTime !== y.publishTime)
      fail(`${what}: another sequence number or time`);
    if (Buffer.compare(Buffer.from(x.data), Buffer.from(y.data)) !== 0) fail(`${what}: other bytes`);
    same++;
  }
  if (same !== n) fail(`${same} messages compared, the file has ${n}`);
  ok(`every one of the ${same} messages is the uncompressed export's, byte for byte`);
}
main().catch((e) => fail(e.stack || String(e)));
