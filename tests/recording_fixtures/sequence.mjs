// Reads a sequence folder in the RELLIS-3D layout (what `slamvdb synth DIR` writes) and lists the
// messages every fixture writer records from it (recording-fixture-spec.md, "content table"), in
// a neutral form that ros_messages.mjs turns into ROS 1 or ROS 2 message objects. Nothing here
// comes from slamvdb's own code: the files are parsed from their documented formats.
import fs from "node:fs";
import path from "node:path";
import zlib from "node:zlib";

export class UsageError extends Error {}

// Decimal seconds ("1700000000.100000", "1700000000_035") -> BigInt nanoseconds, exactly.
export function secondsToNs(text) {
  const m = /^(-?)(\d+)(?:[._](\d*))?$/.exec(text.trim());
  if (!m) throw new UsageError(`not a time stamp in seconds: "${text}"`);
  const fraction = ((m[3] ?? "") + "000000000").slice(0, 9);
  const ns = BigInt(m[2]) * 1000000000n + BigInt(fraction);
  return m[1] === "-" ? -ns : ns;
}

// Width and height from a JPEG's SOFn segment.
function jpegSize(bytes, file) {
  let i = 2;
  while (i + 9 < bytes.length) {
    if (bytes[i] !== 0xff) throw new UsageError(`${file}: not a JPEG file (bad marker at byte ${i})`);
    const marker = bytes[i + 1];
    const length = bytes.readUInt16BE(i + 2);
    if (marker >= 0xc0 && marker <= 0xcf && marker !== 0xc4 && marker !== 0xc8 && marker !== 0xcc)
      return { height: bytes.readUInt16BE(i + 5), width: bytes.readUInt16BE(i + 7) };
    i += 2 + length;
  }
  throw new UsageError(`${file}: no JPEG frame header found`);
}

// An 8-bit greyscale, non-interlaced PNG (what the label images are) -> {width, height, pixels}.
export function decodeGreyPng(bytes, file) {
  if (bytes.readUInt32BE(0) !== 0x89504e47) throw new UsageError(`${file}: not a PNG file`);
  let pos = 8, width = 0, height = 0;
  const idat = [];
  while (pos + 8 <= bytes.length) {
    const length = bytes.readUInt32BE(pos);
    const type = bytes.toString("latin1", pos + 4, pos + 8);
    const data = bytes.subarray(pos + 8, pos + 8 + length);
    if (type === "IHDR") {
      width = data.readUInt32BE(0);
      height = data.readUInt32BE(4);
      if (data[8] !== 8 || data[9] !== 0 || data[12] !== 0)
        throw new UsageError(`${file}: only 8-bit greyscale non-interlaced PNGs are read (depth ${data[8]}, colour type ${data[9]})`);
    } else if (type === "IDAT") {
      idat.push(data);
    } else if (type === "IEND") {
      break;
    }
    pos += 12 + length;
  }
  const raw = zlib.inflateSync(Buffer.concat(idat));
  const pixels = Buffer.alloc(width * height);
  for (let y = 0; y < height; ++y) {
    const filter = raw[y * (width + 1)];
    const line = raw.subarray(y * (width + 1) + 1, (y + 1) * (width + 1));
    for (let x = 0; x < width; ++x) {
      const a = x > 0 ? pixels[y * width + x - 1] : 0;
      const b = y > 0 ? pixels[(y - 1) * width + x] : 0;
      const c = x > 0 && y > 0 ? pixels[(y - 1) * width + x - 1] : 0;
      let predictor = 0;
      if (filter === 1) predictor = a;
      else if (filter === 2) predictor = b;
      else if (filter === 3) predictor = (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      } else if (filter !== 0) throw new UsageError(`${file}: unknown PNG filter ${filter}`);
      pixels[y * width + x] = (line[x] + predictor) & 0xff;
    }
  }
  return { width, height, pixels };
}

// "frame000104-1581624663_149.jpg" -> stamp in ns.
function stampOfFrameName(name) {
  const m = /^frame\d+-(\d+_\d+)\./.exec(name);
  if (!m) throw new UsageError(`image ${name} is not named frameNNNNNN-SECONDS_FRACTION`);
  return secondsToNs(m[1]);
}

// Rotation matrix (row-major 3x3) -> unit quaternion {w, x, y, z}.
export function quaternionOf(r) {
  const [m00, m01, m02, m10, m11, m12, m20, m21, m22] = r;
  const trace = m00 + m11 + m22;
  let w, x, y, z;
  if (trace > 0) {
    const s = Math.sqrt(trace + 1) * 2;
    w = s / 4; x = (m21 - m12) / s; y = (m02 - m20) / s; z = (m10 - m01) / s;
  } else if (m00 > m11 && m00 > m22) {
    const s = Math.sqrt(1 + m00 - m11 - m22) * 2;
    w = (m21 - m12) / s; x = s / 4; y = (m01 + m10) / s; z = (m02 + m20) / s;
  } else if (m11 > m22) {
    const s = Math.sqrt(1 + m11 - m00 - m22) * 2;
    w = (m02 - m20) / s; x = (m01 + m10) / s; y = s / 4; z = (m12 + m21) / s;
  } else {
    const s = Math.sqrt(1 + m22 - m00 - m11) * 2;
    w = (m10 - m01) / s; x = (m02 + m20) / s; y = (m12 + m21) / s; z = s / 4;
  }
  const n = Math.hypot(w, x, y, z);
  return { w: w / n, x: x / n, y: y / n, z: z / n };
}

// transforms.yaml (the block form slamvdb and RELLIS-3D write): q {w x y z} and t {x y z}.
function readExtrinsics(file) {
  const text = fs.readFileSync(file, "utf8");
  const number = (block, key) => {
    const m = new RegExp(`${block}:[\\s\\S]*?\\b${key}:\\s*([-+0-9.eE]+)`).exec(text);
    if (!m) throw new UsageError(`${file}: no ${block}.${key}`);
    return Number(m[1]);
  };
  return {
    rotation: { w: number("q", "w"), x: number("q", "x"), y: number("q", "y"), z: number("q", "z") },
    translation: { x: number("t", "x"), y: number("t", "y"), z: number("t", "z") },
  };
}

// q = a * b (quaternions {w, x, y, z}).
function multiplyQuaternions(a, b) {
  return {
    w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
    x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
    y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
    z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
  };
}

// The messages of the content table, in time order (equal stamps in table order).
// options: {maxScans, padding, organised, pointTimesDir, tfPoses, movingCamera}
//   tfPoses: the ground-truth poses also on /tf (parent "map", child "os1_sensor", one per scan).
//   movingCamera (rad/s, may be 0): the LiDAR-camera joint on /tf instead of /tf_static, one per
//   camera image, turned about the LiDAR's z axis by movingCamera x (image stamp - first scan stamp).
export function readSequence(dir, options = {}) {
  const need = (name) => {
    const p = path.join(dir, name);
    if (!fs.existsSync(p)) throw new UsageError(`${dir} is not a sequence folder: ${name} is missing`);
    return p;
  };
  const stamps = fs.readFileSync(need("times.txt"), "utf8").split("\n").filter((l) => l.trim()).map(secondsToNs);
  const scanDir = need("os1_cloud_node_kitti_bin");
  const scans = fs.readdirSync(scanDir).filter((f) => f.endsWith(".bin")).sort();
  if (scans.length !== stamps.length)
    throw new UsageError(`${dir}: ${scans.length} scans but ${stamps.length} stamps in times.txt`);
  const poses = fs.readFileSync(need("poses.txt"), "utf8").split("\n").filter((l) => l.trim())
    .map((l) => l.trim().split(/\s+/).map(Number));
  if (poses.length !== stamps.length) throw new UsageError(`${dir}: ${poses.length} poses for ${stamps.length} scans`);
  const count = Math.min(scans.length, options.maxScans ?? Infinity);
  const lastStamp = stamps[count - 1];
  const [fx, fy, cx, cy] = fs.readFileSync(need("camera_info.txt"), "utf8").split("\n")[0].trim().split(/\s+/).map(Number);
  const distortionLine = fs.readFileSync(need("camera_info.txt"), "utf8").split("\n")[1] ?? "";
  const distortion = distortionLine.trim() ? distortionLine.trim().split(/\s+/).map(Number) : [0, 0, 0, 0, 0];
  const extrinsics = readExtrinsics(need("transforms.yaml"));

  const messages = [];
  const add = (topic, kind, stamp, content) => messages.push({ topic, kind, stamp, content, order: messages.length });
  if (options.movingCamera === undefined)
    add("/tf_static", "tf", stamps[0], { parent: "os1_sensor", child: "pylon_camera", ...extrinsics });
  for (let i = 0; i < count; ++i) {
    const bin = fs.readFileSync(path.join(scanDir, scans[i]));
    if (bin.length % 16 !== 0) throw new UsageError(`${scans[i]}: size ${bin.length} is not a multiple of 16`);
    let times = null;
    if (options.pointTimesDir) {
      times = fs.readFileSync(path.join(options.pointTimesDir, scans[i]));
      if (times.length !== bin.length / 4) throw new UsageError(`${options.pointTimesDir}/${scans[i]}: one uint32 per point expected`);
    }
    add("/os1_cloud_node/points", "cloud", stamps[i], { xyzi: bin, times, padding: options.padding ?? 0, organised: options.organised ?? 0 });
    const p = poses[i];
    add("/ground_truth/odom", "odom", stamps[i], {
      rotation: quaternionOf([p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]]),
      translation: { x: p[3], y: p[7], z: p[11] },
    });
    if (options.tfPoses)
      add("/tf", "tf", stamps[i], {
        parent: "map", child: "os1_sensor",
        rotation: quaternionOf([p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]]),
        translation: { x: p[3], y: p[7], z: p[11] },
      });
  }
  const imageDir = need("pylon_camera_node");
  for (const name of fs.readdirSync(imageDir).filter((f) => f.endsWith(".jpg")).sort()) {
    const stamp = stampOfFrameName(name);
    if (stamp > lastStamp) continue;
    const jpeg = fs.readFileSync(path.join(imageDir, name));
    const { width, height } = jpegSize(jpeg, name);
    add("/pylon_camera_node/image_raw/compressed", "jpeg", stamp, { jpeg });
    add("/pylon_camera_node/camera_info", "camera_info", stamp, { width, height, fx, fy, cx, cy, distortion });
    if (options.movingCamera !== undefined) {
      const angle = options.movingCamera * (Number(stamp - stamps[0]) / 1e9);
      const turn = { w: Math.cos(angle / 2), x: 0, y: 0, z: Math.sin(angle / 2) };
      const t = extrinsics.translation;
      const [c, s] = [Math.cos(angle), Math.sin(angle)];
      add("/tf", "tf", stamp, {
        parent: "os1_sensor", child: "pylon_camera",
        rotation: multiplyQuaternions(turn, extrinsics.rotation),
        translation: { x: c * t.x - s * t.y, y: s * t.x + c * t.y, z: t.z },
      });
    }
  }
  const labelDir = path.join(dir, "pylon_camera_node_label_id");
  if (fs.existsSync(labelDir)) {
    for (const name of fs.readdirSync(labelDir).filter((f) => f.endsWith(".png")).sort()) {
      const stamp = stampOfFrameName(name);
      if (stamp > lastStamp) continue;
      add("/pylon_camera_node_label_id/image", "label", stamp, decodeGreyPng(fs.readFileSync(path.join(labelDir, name)), name));
    }
  }
  messages.sort((a, b) => (a.stamp < b.stamp ? -1 : a.stamp > b.stamp ? 1 : a.order - b.order));
  return messages;
}
