#!/usr/bin/env node
// Writes a sequence folder (slamvdb synth) as an MCAP file with @mcap/core's McapWriter: profile
// ros1 (ROS 1 serialization by @foxglove/rosmsg-serialization, ros1msg schemas) or ros2 (CDR by
// @foxglove/rosmsg2-serialization, ros2msg schemas). Chunks are compressed by piping their bytes
// through Debian's `zstd` / `lz4` command-line tools (the standard zstd and LZ4 frame formats).
// A manifest (--manifest FILE, JSON lines) lists every message written, in writing order: topic,
// type, log time, size and CRC-32 of its serialized bytes, for tests to compare what they read.
import fs from "node:fs";
import { execFileSync } from "node:child_process";
import { McapWriter } from "@mcap/core";
import { manifestLine, parseArguments, runMain, writeManifest } from "./args.mjs";
import { readSequence, UsageError } from "./sequence.mjs";
import { makeSerializers, messageObject, ros2Name, TYPE_OF_KIND } from "./ros_messages.mjs";

const HELP = `usage: node write_mcap.mjs SEQUENCE_DIR OUT.mcap [options]
  --profile ros1|ros2          serialization (default ros2: CDR)
  --compression none|lz4|zstd  chunk compression (default none)
  --no-summary                 no summary section (no chunk index, statistics or repeated channels)
  --unchunked                  messages in the data section, not in chunks (implies no chunk index)
  --chunk-size BYTES           target uncompressed chunk size (default 1048576)
  --order time|by-topic        writing order: by log time (default), or topic after topic (chunks then
                               overlap in time, as a recorder with one writer thread per topic makes)
  --big-endian                 CDR with big-endian encapsulation (ros2 profile)
  --max-scans K                only the first K scans (and the images up to the last of them)
  --padding P                  P unused bytes at the end of every point (point_step 20 + P)
  --organised H                organised clouds of H rows
  --point-times DIR            per-point times: DIR/NNNNNN.bin, one uint32 (ns since scan start) per point
  --log-time-offset S          log time = header stamp + S seconds
  --tf-poses                   the ground-truth poses also on /tf (map -> os1_sensor, one per scan)
  --moving-camera R            the LiDAR-camera joint on /tf (not /tf_static), one per image, turned
                               about the LiDAR's z by R rad/s since the first scan (R may be 0)
  --json-channel               also a channel with message encoding json (/diagnostics_json, 3 messages)
  --manifest FILE              JSON lines: topic, type, log_time_ns, size, crc32 of every message written
  --help`;

// write_mcap.mjs's own options (the shared ones are in args.mjs).
function ownOption(a, o, read) {
  if (a === "--profile") o.profile = read.choice(a, ["ros1", "ros2"]);
  else if (a === "--compression") o.compression = read.choice(a, ["none", "lz4", "zstd"]);
  else if (a === "--no-summary") o.summary = false;
  else if (a === "--unchunked") o.chunked = false;
  else if (a === "--chunk-size") o.chunkSize = read.int(a);
  else if (a === "--order") o.order = read.choice(a, ["time", "by-topic"]);
  else if (a === "--json-channel") o.jsonChannel = true;
  else return false;
  return true;
}

function parseMcapArguments(argv) {
  const o = parseArguments(argv, HELP, { profile: "ros2", compression: "none", summary: true, chunked: true,
    chunkSize: 1 << 20, order: "time", jsonChannel: false }, ownOption, "expected SEQUENCE_DIR and OUT.mcap");
  if (o.bigEndian && o.profile !== "ros2") throw new UsageError("--big-endian needs --profile ros2");
  return o;
}

// A chunk's bytes through the zstd or lz4 command-line tool (standard frame formats).
function compressor(compression) {
  if (compression === "none") return undefined;
  const args = compression === "zstd" ? ["-q", "-c", "-3"] : ["-q", "-c"];
  return (data) => ({ compression, compressedData: execFileSync(compression, args, { input: data, maxBuffer: 1 << 30 }) });
}

// Writes to a file descriptor; McapWriter wants an asynchronous writable that knows its position.
class FileWritable {
  constructor(file) { this.fd = fs.openSync(file, "w"); this.offset = 0n; }
  async write(buffer) { fs.writeSync(this.fd, buffer); this.offset += BigInt(buffer.byteLength); }
  position() { return this.offset; }
  close() { fs.closeSync(this.fd); }
}

async function main() {
  const o = parseMcapArguments(process.argv.slice(2));
  const [sequenceDir, outFile] = o.positional;
  const ros2 = o.profile === "ros2";
  const messages = readSequence(sequenceDir, o);
  if (o.order === "by-topic") {
    const topics = [...new Set(messages.map((m) => m.topic))];
    messages.sort((a, b) => topics.indexOf(a.topic) - topics.indexOf(b.topic) || (a.stamp < b.stamp ? -1 : a.stamp > b.stamp ? 1 : 0));
  }
  const serializer = makeSerializers(ros2, o.bigEndian);
  const file = new FileWritable(outFile);
  const writer = new McapWriter({
    writable: file, useChunks: o.chunked, chunkSize: o.chunkSize, compressChunk: compressor(o.compression),
    useStatistics: o.summary, useSummaryOffsets: o.summary, useChunkIndex: o.summary && o.chunked,
    useMessageIndex: o.chunked, repeatSchemas: o.summary, repeatChannels: o.summary,
    useAttachmentIndex: o.summary, useMetadataIndex: o.summary,
  });
  await writer.start({ profile: o.profile, library: "slamvdb recording fixtures (@mcap/core)" });
  const channels = new Map();
  const channelOf = async (topic, type) => {
    if (!channels.has(topic)) {
      const s = serializer(type);
      const schemaId = await writer.registerSchema({
        name: ros2 ? ros2Name(type) : type, encoding: ros2 ? "ros2msg" : "ros1msg", data: new TextEncoder().encode(s.text),
      });
      const metadata = new Map(ros2 ? [["offered_qos_profiles", ""]] : [["md5sum", s.md5], ["callerid", "/slamvdb_fixture"]]);
      channels.set(topic, await writer.registerChannel({ topic, schemaId, messageEncoding: ros2 ? "cdr" : "ros1", metadata }));
    }
    return channels.get(topic);
  };
  const manifest = [];
  const record = async (topic, type, logTime, data, channelId) => {
    await writer.addMessage({ channelId, sequence: manifest.length, logTime, publishTime: logTime, data });
    manifest.push(manifestLine(topic, type, logTime, data));
  };
  for (const m of messages) {
    const type = TYPE_OF_KIND[m.kind];
    const channelId = await channelOf(m.topic, type);
    await record(m.topic, type, m.stamp + o.logTimeOffset, serializer(type).write(messageObject(m, ros2)), channelId);
  }
  if (o.jsonChannel) {
    const schemaId = await writer.registerSchema({ name: "Diagnostics", encoding: "jsonschema", data: new TextEncoder().encode('{"type":"object"}') });
    const channelId = await writer.registerChannel({ topic: "/diagnostics_json", schemaId, messageEncoding: "json", metadata: new Map() });
    for (let i = 0; i < 3; ++i)
      await record("/diagnostics_json", "Diagnostics", messages[0].stamp + o.logTimeOffset + BigInt(i) * 1000000n,
        new TextEncoder().encode(JSON.stringify({ level: i })), channelId);
  }
  await writer.end();
  file.close();
  writeManifest(o.manifest, manifest);
}

runMain("write_mcap.mjs", main);
