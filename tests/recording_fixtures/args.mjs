// What the fixture writers (write_mcap.mjs, write_rosbag2.mjs) share around their own work: the
// command line (--help, the options of the sequence read, --big-endian, --manifest, two
// positional arguments), the manifest of what they wrote, and the exit status (2 for a usage
// error, 1 for anything else, the message prefixed with the script's name).
import fs from "node:fs";
import zlib from "node:zlib";
import { secondsToNs, UsageError } from "./sequence.mjs";

// Parses `argv` into `defaults` plus the shared options. `own(a, o, read)` handles the writer's own
// option `a` (reading its value with read.value(), read.int(name) or read.choice(name, allowed))
// and returns false when `a` is not one of them. `positionalError`: the message when there are not
// exactly two positional arguments.
export function parseArguments(argv, help, defaults, own, positionalError) {
  const o = { bigEndian: false, logTimeOffset: 0n, ...defaults, positional: [] };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    const value = () => {
      if (i + 1 >= argv.length) throw new UsageError(`${a} needs a value`);
      return argv[++i];
    };
    const int = (name) => {
      const v = value();
      if (!/^\d+$/.test(v)) throw new UsageError(`${name} must be a non-negative integer, not "${v}"`);
      return Number(v);
    };
    const choice = (name, allowed) => {
      const v = value();
      if (!allowed.includes(v)) throw new UsageError(`${name} must be one of ${allowed.join(", ")}, not "${v}"`);
      return v;
    };
    if (a === "--help" || a === "-h") { console.log(help); process.exit(0); }
    else if (own(a, o, { value, int, choice })) continue;
    else if (a === "--big-endian") o.bigEndian = true;
    else if (a === "--max-scans") o.maxScans = int(a);
    else if (a === "--padding") o.padding = int(a);
    else if (a === "--organised") o.organised = int(a);
    else if (a === "--point-times") o.pointTimesDir = value();
    else if (a === "--tf-poses") o.tfPoses = true;
    else if (a === "--moving-camera") {
      const v = value();
      if (!/^-?\d+(\.\d*)?$/.test(v)) throw new UsageError(`--moving-camera must be radians per second, not "${v}"`);
      o.movingCamera = Number(v);
    }
    else if (a === "--log-time-offset") {
      const v = value();
      if (!/^-?\d+(\.\d*)?$/.test(v)) throw new UsageError(`--log-time-offset must be seconds, not "${v}"`);
      o.logTimeOffset = secondsToNs(v);
    } else if (a === "--manifest") o.manifest = value();
    else if (a.startsWith("-")) throw new UsageError(`unknown option ${a}`);
    else o.positional.push(a);
  }
  if (o.positional.length !== 2) throw new UsageError(positionalError);
  return o;
}

// One manifest line: topic, type, log time, size and CRC-32 of a message's serialized bytes.
export function manifestLine(topic, type, logTime, data) {
  return JSON.stringify({ topic, type, log_time_ns: logTime.toString(), size: data.length, crc32: zlib.crc32(data) });
}

// The manifest (JSON lines, in writing order), when --manifest asked for one.
export function writeManifest(file, lines) {
  if (file) fs.writeFileSync(file, lines.join("\n") + "\n");
}

// Runs `main` (synchronous or async) and exits as the writers do on an error.
export function runMain(script, main) {
  Promise.resolve().then(main).catch((e) => {
    console.error(`${script}: ${e.message}`);
    if (!(e instanceof UsageError) && process.env.DEBUG) console.error(e.stack);
    process.exit(e instanceof UsageError ? 2 : 1);
  });
}
