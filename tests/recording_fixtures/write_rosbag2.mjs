#!/usr/bin/env node
// Writes a sequence folder (slamvdb synth) as a ROS 2 bag with the sqlite3 storage, as rosbag2
// writes one: a folder with metadata.yaml and one or more .db3 files (write_db3.py makes them with
// Python's sqlite3 module; Node has no SQLite). Messages are CDR from
// @foxglove/rosmsg2-serialization. Compression as rosbag2's zstd plugin does it, through Debian's
// `zstd` tool: FILE (each .db3 compressed whole into .db3.zstd) or MESSAGE (each message's data
// one zstd frame). A manifest (--manifest FILE, JSON lines) lists every message in writing order:
// topic, type, log time, size and CRC-32 of its (uncompressed) CDR bytes.
import fs from "node:fs";
import path from "node:path";
import { execFileSync } from "node:child_process";
import { fileURLToPath } from "node:url";
import { manifestLine, parseArguments, runMain, writeManifest } from "./args.mjs";
import { readSequence, UsageError } from "./sequence.mjs";
import { makeSerializers, messageObject, ros2Name, TYPE_OF_KIND } from "./ros_messages.mjs";

const HELP = `usage: node write_rosbag2.mjs SEQUENCE_DIR OUT_DIR [options]
  --split N                          split over N .db3 files (consecutive in time; default 1)
  --compression none|zstd-file|zstd-message
                                     rosbag2's compression_mode FILE or MESSAGE, format zstd (default none)
  --ros-distro humble|iron|jazzy     sqlite schema 3 (humble) or 4, metadata version 5, 8 or 9 (default jazzy)
  --no-metadata                      no metadata.yaml (only the .db3 files)
  --big-endian                       CDR with big-endian encapsulation
  --max-scans K, --padding P, --organised H, --point-times DIR, --log-time-offset S,
  --tf-poses, --moving-camera R      as for write_mcap.mjs
  --python PATH                      the Python that writes the .db3 files (default python3)
  --manifest FILE                    JSON lines: topic, type, log_time_ns, size, crc32 of every message
  --help`;

const DISTROS = { humble: { schema: 3, version: 5 }, iron: { schema: 4, version: 8 }, jazzy: { schema: 4, version: 9 } };

// write_rosbag2.mjs's own options (the shared ones are in args.mjs).
function ownOption(a, o, read) {
  if (a === "--split") o.split = read.int(a);
  else if (a === "--compression") o.compression = read.choice(a, ["none", "zstd-file", "zstd-message"]);
  else if (a === "--ros-distro") o.distro = read.choice(a, Object.keys(DISTROS));
  else if (a === "--no-metadata") o.metadata = false;
  else if (a === "--python") o.python = read.value();
  else return false;
  return true;
}

function parseRosbag2Arguments(argv) {
  const o = parseArguments(argv, HELP, { split: 1, compression: "none", distro: "jazzy", metadata: true,
    python: "python3" }, ownOption, "expected SEQUENCE_DIR and OUT_DIR");
  if (o.split < 1) throw new UsageError("--split must be at least 1");
  return o;
}

// rosbag2's default QoS profile of a recorded topic, as Humble serializes it (a YAML string).
const QOS = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 9223372036\n    nsec: 854775807\n"
  + "  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n"
  + "    nsec: 854775807\n  avoid_ros_namespace_conventions: false";

const quote = (s) => JSON.stringify(s);  // a YAML double-quoted scalar

function metadataYaml(o, topics, files, messages) {
  const distro = DISTROS[o.distro];
  const first = messages[0].logTime, last = messages[messages.length - 1].logTime;
  const lines = ["rosbag2_bagfile_information:", `  version: ${distro.version}`, "  storage_identifier: sqlite3",
    "  duration:", `    nanoseconds: ${last - first}`, "  starting_time:", `    nanoseconds_since_epoch: ${first}`,
    `  message_count: ${messages.length}`, "  topics_with_message_count:"];
  for (const t of topics) {
    lines.push("    - topic_metadata:", `        name: ${t.name}`, `        type: ${t.type}`, "        serialization_format: cdr");
    lines.push(distro.version >= 9 ? "        offered_qos_profiles: []" : `        offered_qos_profiles: ${quote(QOS)}`);
    if (distro.version >= 7) lines.push('        type_description_hash: ""');
    lines.push(`      message_count: ${messages.filter((m) => m.topic === t.name).length}`);
  }
  const mode = o.compression === "none" ? "" : o.compression === "zstd-file" ? "FILE" : "MESSAGE";
  lines.push(`  compression_format: ${quote(mode ? "zstd" : "")}`, `  compression_mode: ${quote(mode)}`, "  relative_file_paths:");
  for (const f of files) lines.push(`    - ${f.name}`);
  lines.push("  files:");
  for (const f of files)
    lines.push(`    - path: ${f.name}`, "      starting_time:", `        nanoseconds_since_epoch: ${f.first}`,
      "      duration:", `        nanoseconds: ${f.last - f.first}`, `      message_count: ${f.count}`);
  if (distro.version >= 6) lines.push("  custom_data: ~");
  if (distro.version >= 8) lines.push(`  ros_distro: ${o.distro}`);
  return lines.join("\n") + "\n";
}

function main() {
  const o = parseRosbag2Arguments(process.argv.slice(2));
  const [sequenceDir, outDir] = o.positional;
  if (fs.existsSync(outDir) && fs.readdirSync(outDir).length > 0) throw new UsageError(`${outDir} exists and is not empty`);
  fs.mkdirSync(outDir, { recursive: true });
  const name = path.basename(path.resolve(outDir));
  const serializer = makeSerializers(true, o.bigEndian);
  const topics = [];
  const messages = readSequence(sequenceDir, o).map((m) => {
    const type = TYPE_OF_KIND[m.kind];
    let topic = topics.find((t) => t.name === m.topic);
    if (!topic) topics.push((topic = { id: topics.length + 1, name: m.topic, type: ros2Name(type), plainType: type }));
    return { topic: m.topic, topicId: topic.id, plainType: type, logTime: m.stamp + o.logTimeOffset, data: serializer(type).write(messageObject(m, true)) };
  });
  const definitions = topics.map((t) => ({ topic_type: t.type, encoding: "ros2msg", encoded_message_definition: serializer(t.plainType).text }));
  const writerScript = path.join(path.dirname(fileURLToPath(import.meta.url)), "write_db3.py");
  const files = [];
  const perFile = Math.ceil(messages.length / o.split);
  for (let f = 0; f < o.split; ++f) {
    const part = messages.slice(f * perFile, (f + 1) * perFile);
    if (part.length === 0) throw new UsageError(`--split ${o.split}: only ${messages.length} messages`);
    const db3 = `${name}_${f}.db3`;
    const chunks = [Buffer.from(JSON.stringify({
      topics: topics.map((t) => ({ id: t.id, name: t.name, type: t.type, serialization_format: "cdr", offered_qos_profiles: QOS, type_description_hash: "" })),
      definitions,
    }) + "\n")];
    for (const m of part) {
      // MESSAGE mode: one frame per message, its size in the frame header (rosbag2 compresses with ZSTD_compressCCtx).
      const data = o.compression === "zstd-message"
        ? execFileSync("zstd", ["-q", "-c", `--stream-size=${m.data.length}`], { input: m.data, maxBuffer: 1 << 30 })
        : m.data;
      const head = Buffer.alloc(16);
      head.writeUInt32LE(m.topicId, 0);
      head.writeBigInt64LE(m.logTime, 4);
      head.writeUInt32LE(data.length, 12);
      chunks.push(head, Buffer.from(data.buffer, data.byteOffset, data.byteLength));
    }
    execFileSync(o.python, [writerScript, path.join(outDir, db3), String(DISTROS[o.distro].schema), o.distro],
      { input: Buffer.concat(chunks), stdio: ["pipe", "inherit", "inherit"] });
    let fileName = db3;
    if (o.compression === "zstd-file") {
      // FILE mode: the whole .db3 streamed through zstd (no size in the frame header, as rosbag2's streaming compressor).
      fileName = `${db3}.zstd`;
      fs.writeFileSync(path.join(outDir, fileName), execFileSync("zstd", ["-q", "-c"], { input: fs.readFileSync(path.join(outDir, db3)), maxBuffer: 1 << 30 }));
      fs.rmSync(path.join(outDir, db3));
    }
    files.push({ name: fileName, first: part[0].logTime, last: part[part.length - 1].logTime, count: part.length });
  }
  if (o.metadata) fs.writeFileSync(path.join(outDir, "metadata.yaml"), metadataYaml(o, topics, files, messages));
  writeManifest(o.manifest, messages.map((m) => manifestLine(m.topic, m.plainType, m.logTime, m.data)));
}

runMain("write_rosbag2.mjs", main);
