#!/usr/bin/env node
// Reads an MCAP file with readers that are not slamvdb's, to check the files slamvdb's own MCAP
// writer makes (`slamvdb convert`, `slamvdb synth --format mcap`): @mcap/core's indexed reader
// (summary CRC, chunk indexes, message indexes, chunk CRCs checked) and its stream reader (every
// record in file order, CRCs checked: schemas and channels must come before their messages), the
// data section CRC recomputed with Node's zlib, and every message decoded from its schema's
// ros2msg text by @foxglove/rosmsg + @foxglove/rosmsg2-serialization (CDR).
//
//   node read_mcap.mjs FILE.mcap
// prints one JSON object: profile, library, statistics, per topic the schema, encoding and
// message count, the record counts of the stream, and a few decoded fields of the first message
// of each topic (points, image sizes, poses), for the tests to compare with the sequence.
import fs from "node:fs";
import zlib from "node:zlib";
import { execFileSync } from "node:child_process";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import rosmsg from "@foxglove/rosmsg";
import ros2Serialization from "@foxglove/rosmsg2-serialization";

const args = process.argv.slice(2);
if (args.includes("--help") || args.includes("-h")) {
  console.log("usage: node read_mcap.mjs FILE.mcap (see the comment at the top)");
  process.exit(0);
}
if (args.length !== 1) {
  console.error("read_mcap.mjs: expected one MCAP file\nusage: node read_mcap.mjs FILE.mcap");
  process.exit(2);
}

// Chunks through Debian's zstd / lz4 tools (standard frame formats), as the fixture writers do.
const decompressHandlers = {
  zstd: (data, size) => new Uint8Array(execFileSync("zstd", ["-d", "-q", "-c"], { input: data, maxBuffer: Number(size) + 1024 })),
  lz4: (data, size) => new Uint8Array(execFileSync("lz4", ["-d", "-q", "-c"], { input: data, maxBuffer: Number(size) + 1024 })),
};

// The first few decoded fields of a message, by its schema name.
function fields(schema, m) {
  const time = (t) => `${t.sec}.${String(t.nanosec).padStart(9, "0")}`;
  const quaternion = (q) => [q.x, q.y, q.z, q.w];
  switch (schema) {
    case "sensor_msgs/msg/PointCloud2": {
      const view = new DataView(m.data.buffer, m.data.byteOffset, m.data.byteLength);
      const offset = (name) => m.fields.find((f) => f.name === name)?.offset;
      const point = (i) => ({
        x: view.getFloat32(i * m.point_step + offset("x"), true),
        y: view.getFloat32(i * m.point_step + offset("y"), true),
        z: view.getFloat32(i * m.point_step + offset("z"), true),
        intensity: offset("intensity") === undefined ? null : view.getFloat32(i * m.point_step + offset("intensity"), true),
        t: view.getUint32(i * m.point_step + offset("t"), true),
      });
      return {
        stamp: time(m.header.stamp), frame_id: m.header.frame_id, height: m.height, width: m.width,
        fields: m.fields.map((f) => `${f.name}:${f.offset}:${f.datatype}`), point_step: m.point_step,
        row_step: m.row_step, data_bytes: m.data.byteLength, first_point: point(0), last_point: point(m.width * m.height - 1),
      };
    }
    case "sensor_msgs/msg/CompressedImage":
      return { stamp: time(m.header.stamp), frame_id: m.header.frame_id, format: m.format, bytes: m.data.byteLength,
               crc32: zlib.crc32(m.data) };
    case "sensor_msgs/msg/Image":
      return { stamp: time(m.header.stamp), frame_id: m.header.frame_id, width: m.width, height: m.height,
               encoding: m.encoding, step: m.step, bytes: m.data.byteLength, crc32: zlib.crc32(m.data) };
    case "sensor_msgs/msg/CameraInfo":
      return { stamp: time(m.header.stamp), width: m.width, height: m.height, distortion_model: m.distortion_model,
               d: Array.from(m.d), k: Array.from(m.k), p: Array.from(m.p) };
    case "tf2_msgs/msg/TFMessage":
      return { transforms: m.transforms.map((t) => ({ parent: t.header.frame_id, child: t.child_frame_id,
        translation: [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
        rotation: quaternion(t.transform.rotation) })) };
    case "nav_msgs/msg/Odometry":
      return { stamp: time(m.header.stamp), frame_id: m.header.frame_id, child_frame_id: m.child_frame_id,
               position: [m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z],
               orientation: quaternion(m.pose.pose.orientation) };
  }
  return {};
}

async function main() {
  const file = args[0];
  const bytes = fs.readFileSync(file);
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => new Uint8Array(bytes.buffer, bytes.byteOffset + Number(offset), Number(size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });  // checks the summary CRC
  const out = {
    profile: reader.header.profile, library: reader.header.library, chunks: reader.chunkIndexes.length,
    statistics: reader.statistics && {
      message_count: Number(reader.statistics.messageCount), chunk_count: reader.statistics.chunkCount,
      channel_count: reader.statistics.channelCount, schema_count: reader.statistics.schemaCount,
    },
    topics: {}, first: {}, records: {},
  };
  const decoders = new Map();
  for (const [id, schema] of reader.schemasById) {
    if (schema.encoding !== "ros2msg") throw new Error(`schema ${schema.name}: encoding ${schema.encoding}, not ros2msg`);
    const text = new TextDecoder().decode(schema.data);
    decoders.set(id, new ros2Serialization.MessageReader(rosmsg.parse(text, { ros2: true })));
  }
  let lastLogTime = -1n;
  for await (const message of reader.readMessages({ validateCrcs: true })) {  // in log-time order, chunk CRCs checked
    const channel = reader.channelsById.get(message.channelId);
    const schema = reader.schemasById.get(channel.schemaId);
    if (message.logTime < lastLogTime) throw new Error(`${channel.topic}: messages out of log-time order`);
    lastLogTime = message.logTime;
    const decoded = decoders.get(channel.schemaId).readMessage(message.data);
    const topic = (out.topics[channel.topic] ??= { schema: schema.name, message_encoding: channel.messageEncoding, count: 0 });
    topic.count += 1;
    if (!(channel.topic in out.first)) out.first[channel.topic] = { log_time_ns: message.logTime.toString(), ...fields(schema.name, decoded) };
  }
  // Every record in file order with CRCs checked; the data section CRC from Node's zlib.
  const stream = new McapStreamReader({ validateCrcs: true, decompressHandlers });
  stream.append(bytes);
  let dataEndOffset = -1, dataSectionCrc = 0, messagesInStream = 0, offset = 0;
  for (let record; (record = stream.nextRecord());) {
    out.records[record.type] = (out.records[record.type] ?? 0) + 1;
    if (record.type === "Message") ++messagesInStream;
    if (record.type === "DataEnd") dataSectionCrc = record.dataSectionCrc;
  }
  if (!stream.done()) throw new Error("the stream reader did not reach the end magic");
  // The DataEnd record (13 bytes) ends where the summary starts.
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const summaryStart = Number(view.getBigUint64(bytes.length - 8 - 20, true));
  dataEndOffset = summaryStart - 13;
  if (bytes[dataEndOffset] !== 0x0f) throw new Error(`no DataEnd record at ${dataEndOffset}`);
  offset = zlib.crc32(bytes.subarray(0, dataEndOffset));
  out.data_section_crc_ok = dataSectionCrc === offset;
  out.messages_in_stream = messagesInStream;
  console.log(JSON.stringify(out));
}

main().catch((e) => {
  console.error(`read_mcap.mjs: ${e.message}`);
  process.exit(1);
});
