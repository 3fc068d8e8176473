#!/usr/bin/env node
// Independent checker for MCAP files written by `poise record`.
//
// It reads a file with the official MCAP reader (@mcap/core, chunk decompression from
// @mcap/support) and decodes every message with Foxglove's OMG IDL parser and CDR deserializer
// (@foxglove/omgidl-parser, @foxglove/omgidl-serialization). None of this code shares anything
// with the Poise C++ recorder, so a file that passes here is readable by common MCAP tools.
//
// Usage: node mcap_check.mjs [--streaming] [--piece-bytes N] [--dump OUT.jsonl] FILE.mcap
//
//   (default)        indexed read: footer -> summary -> chunk indexes -> message indexes. The file
//                    must be complete (footer, summary section, chunk indexes).
//   --streaming      reads the file front to back in pieces of --piece-bytes (default 65536)
//                    with McapStreamReader. A file cut anywhere (recorder killed) is fine: every
//                    complete record is read and the file is reported with "complete": false.
//   --dump OUT.jsonl one line per message: {"topic","sequence","log_time","publish_time","data"}.
//                    Streaming mode writes them in file order; indexed mode in log_time order
//                    (file order among equal log times), as McapIndexedReader yields them.
//                    "data" is the decoded value: uint64/int64 as decimal strings, typed arrays
//                    (double[64] -> Float64Array) as JSON arrays, NaN/Infinity as the strings
//                    "NaN"/"Infinity"/"-Infinity", enums as their numbers, sequence<string> as
//                    arrays; a message that failed has "data": null and "error": "...".
//
// Checks made on each message: its channel's schema has encoding "omgidl" and the channel has
// message encoding "cdr"; the schema text parses and defines a type named like the schema; the
// message decodes; every bounded string / bounded sequence is within its bound; every enum value
// is one of the enum's values; in plain CDR the decoded value accounts for the whole sample (at
// most 3 bytes of trailing padding). File-level checks: chunk CRCs (both modes), the data section
// CRC when the file has one, and, when the file has a Statistics record, that its counts and
// times match what was read.
//
// Output: one JSON object on stdout (see report() below). uint64 times are decimal strings.
// Exit status: 0 every message decoded and no file-level error (and, indexed, the file is
// complete); 1 otherwise; 2 usage error, or the file is missing, unreadable or not MCAP.

import fs from "node:fs";
import { McapIndexedReader, McapStreamReader, MCAP_MAGIC } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { parseIDL } from "@foxglove/omgidl-parser";
import { MessageReader } from "@foxglove/omgidl-serialization";
import { crc32Init, crc32Update, crc32Final } from "@foxglove/crc";

const USAGE =
  "usage: node mcap_check.mjs [--streaming] [--piece-bytes N] [--dump OUT.jsonl] FILE.mcap";
const MAX_ERRORS = 100;

class UsageError extends Error {}
class NotMcapError extends Error {}

function parseArgs(argv) {
  const opts = { streaming: false, dump: undefined, pieceBytes: 65536, file: undefined };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === "--streaming") {
      opts.streaming = true;
    } else if (a === "--dump" || a === "--piece-bytes") {
      if (i + 1 >= argv.length) throw new UsageError(`${a} needs a value`);
      const v = argv[++i];
      if (a === "--dump") {
        opts.dump = v;
      } else {
        opts.pieceBytes = Number(v);
        if (!Number.isInteger(opts.pieceBytes) || opts.pieceBytes < 1) {
          throw new UsageError(`--piece-bytes wants a positive integer, not '${v}'`);
        }
      }
    } else if (a === "-h" || a === "--help") {
      process.stdout.write(USAGE + "\n");
      process.exit(0);
    } else if (a.startsWith("-") && a !== "-") {
      throw new UsageError(`unknown option '${a}'`);
    } else if (opts.file === undefined) {
      opts.file = a;
    } else {
      throw new UsageError(`only one FILE is accepted ('${opts.file}', '${a}')`);
    }
  }
  if (opts.file === undefined) throw new UsageError("no FILE given");
  return opts;
}

// ---- JSON conversion of decoded values -------------------------------------------------------

// BigInt -> decimal string; typed arrays -> plain arrays; NaN/Infinity -> "NaN"/"Infinity"/
// "-Infinity" (JSON has no such numbers); Maps -> objects.
function jsonReplacer(_key, value) {
  if (typeof value === "bigint") return value.toString();
  if (typeof value === "number" && !Number.isFinite(value)) return String(value);
  if (ArrayBuffer.isView(value) && !(value instanceof DataView)) return Array.from(value);
  if (value instanceof Map) return Object.fromEntries(value);
  return value;
}

// ---- Per-schema decoding ----------------------------------------------------------------------

class SchemaDecoder {
  // Throws with a readable text when the schema is unusable.
  constructor(schema) {
    this.name = schema.name;
    if (schema.encoding !== "omgidl") {
      throw new Error(`schema ${schema.id} '${schema.name}' has encoding '${schema.encoding}', ` +
        "expected 'omgidl'");
    }
    let text;
    try {
      text = new TextDecoder("utf-8", { fatal: true }).decode(schema.data);
    } catch {
      throw new Error(`schema '${schema.name}': data is not UTF-8 text`);
    }
    let defs;
    try {
      defs = parseIDL(text);
    } catch (e) {
      throw new Error(`schema '${schema.name}': parseIDL failed: ${firstLine(e)}`);
    }
    this.defs = new Map(defs.map((d) => [d.name ?? "", d]));
    const root = this.defs.get(schema.name);
    if (root === undefined) {
      throw new Error(`schema '${schema.name}': the IDL text defines no type of that name ` +
        `(it defines ${[...this.defs.keys()].filter(Boolean).join(", ") || "nothing"})`);
    }
    if (root.aggregatedKind !== "struct" && root.aggregatedKind !== "union") {
      throw new Error(`schema '${schema.name}' names a ${root.aggregatedKind}, not a struct`);
    }
    this.root = root;
    this.reader = new MessageReader(schema.name, defs);
    // The size check below knows structs, strings, primitives, arrays and sequences (all Poise
    // uses); a schema with a union is decoded without it.
    this.sizeCheck = !defs.some((d) => d.aggregatedKind === "union");
  }

  // Offset after `value` encoded in plain CDR (XCDR1) from offset `off` (4 = just after the
  // encapsulation header; alignment counts from there, 8 bytes at most). Strings are a uint32
  // length, their UTF-8 bytes and a NUL, as DDS writers send them (an empty string: length 1).
  cdrSize(def, value, off) {
    for (const field of def.definitions) {
      if (field.isConstant === true) continue;
      const v = value[field.name];
      if (field.isArray !== true) {
        off = this.cdrElementSize(field, v, off);
        continue;
      }
      let elements;
      if (field.arrayLengths === undefined) {
        off = align(off, 4) + 4; // sequence length
        elements = v;
      } else {
        elements = field.arrayLengths.length > 1 ? flatten(v, field.arrayLengths.length) : v;
      }
      const size = PRIMITIVE_SIZE[field.type];
      if (field.isComplex !== true && size !== undefined) {
        off = elements.length > 0 ? align(off, size) + size * elements.length : off;
      } else {
        for (const e of elements) off = this.cdrElementSize(field, e, off);
      }
    }
    return off;
  }

  cdrElementSize(field, v, off) {
    if (field.isComplex === true) return this.cdrSize(this.defs.get(field.type), v, off);
    if (field.type === "string") return align(off, 4) + 4 + Buffer.byteLength(v, "utf8") + 1;
    const size = PRIMITIVE_SIZE[field.type];
    if (size === undefined) throw new Error(`no CDR size for type ${field.type}`);
    return align(off, size) + size;
  }

  // Returns the decoded value; throws on any problem.
  decode(data) {
    if (data.byteLength < 4) {
      throw new Error(`sample of ${data.byteLength} bytes has no CDR encapsulation header`);
    }
    const kind = data[1];
    if (data[0] !== 0) {
      throw new Error(`unknown CDR encapsulation ${hex(data.subarray(0, 4))}`);
    }
    const value = this.reader.readMessage(data);
    const problems = [];
    this.validate(this.root, value, "", problems);
    if (problems.length > 0) {
      throw new Error(problems.slice(0, 3).join("; ") + (problems.length > 3 ? "; ..." : ""));
    }
    if ((kind === 0x00 || kind === 0x01) && this.sizeCheck) {
      // Plain CDR (XCDR1): the decoded value must account for the whole sample, up to the at most
      // 3 padding bytes that DDS writers append to reach a multiple of 4.
      const used = this.cdrSize(this.root, value, 4);
      const extra = data.byteLength - used;
      if (extra < 0 || extra > 3) {
        throw new Error(`sample has ${data.byteLength} bytes but the decoded ${this.name} ` +
          `occupies ${used} (header included): ` +
          (extra > 0 ? `${extra} bytes left over` : "overrun (a string that is not UTF-8?)"));
      }
    }
    return value;
  }

  validate(def, value, path, problems) {
    if (def.aggregatedKind !== "struct" || value == null) return; // unions: decode only
    for (const field of def.definitions) {
      if (field.isConstant === true) continue;
      const fpath = path ? `${path}.${field.name}` : field.name;
      let v = value[field.name];
      if (field.isArray === true) {
        const dims = field.arrayLengths;
        if (dims === undefined) {
          if (field.arrayUpperBound !== undefined && v.length > field.arrayUpperBound) {
            problems.push(`${fpath}: sequence of ${v.length} elements exceeds its bound ` +
              `${field.arrayUpperBound}`);
          }
          v = Array.from(v);
        } else {
          v = flatten(v, dims.length);
        }
        v.forEach((e, i) => this.validateElement(field, e, `${fpath}[${i}]`, problems));
      } else {
        this.validateElement(field, v, fpath, problems);
      }
    }
  }

  validateElement(field, v, path, problems) {
    if (field.isComplex === true) {
      const def = this.defs.get(field.type);
      if (def !== undefined) this.validate(def, v, path, problems);
      return;
    }
    if (field.type === "string" && field.upperBound !== undefined) {
      const n = Buffer.byteLength(v, "utf8");
      if (n > field.upperBound) {
        problems.push(`${path}: string of ${n} bytes exceeds its bound ${field.upperBound}`);
      }
    }
    if (field.enumType !== undefined) {
      const e = this.defs.get(field.enumType);
      const values = e?.definitions?.filter((d) => d.isConstant === true).map((d) => d.value);
      if (values !== undefined && !values.includes(v)) {
        problems.push(`${path}: ${v} is not a value of enum ${field.enumType}`);
      }
    }
  }
}

const PRIMITIVE_SIZE = {
  bool: 1, int8: 1, uint8: 1, int16: 2, uint16: 2, int32: 4, uint32: 4, float32: 4,
  int64: 8, uint64: 8, float64: 8,
};

function align(off, n) {
  const r = (off - 4) % n;
  return r === 0 ? off : off + n - r;
}

function flatten(v, depth) {
  if (depth <= 1) return Array.from(v);
  return Array.from(v).flatMap((e) => flatten(e, depth - 1));
}

function hex(bytes) {
  return Buffer.from(bytes.buffer, bytes.byteOffset, bytes.byteLength).toString("hex");
}

function firstLine(e) {
  const text = e instanceof Error ? e.message : String(e);
  const lines = text.split("\n").filter((l) => l.trim() !== "");
  return lines.length <= 6 ? lines.join(" | ") : lines.slice(0, 6).join(" | ") + " | ...";
}

// ---- The check ------------------------------------------------------------------------------

class Check {
  constructor(file, mode, dumpPath) {
    this.file = file;
    this.mode = mode;
    this.complete = false;
    this.header = null;
    this.messages = 0;
    this.decoded = 0;
    this.errors = [];
    this.schemas = new Map(); // id -> Schema record
    this.channels = new Map(); // id -> Channel record
    this.decoders = new Map(); // schema id -> SchemaDecoder | Error
    this.channelCheck = new Map(); // channel id -> null (ok) | Error text
    this.topics = new Map(); // topic -> per-topic summary
    this.perChannel = new Map(); // channel id -> message count
    this.metadata = {};
    this.metadataRecords = 0;
    this.attachments = 0;
    this.chunks = 0;
    this.compressions = {};
    this.statistics = null;
    this.minLogTime = undefined;
    this.maxLogTime = undefined;
    this.extra = {};
    this.dumpFd = dumpPath === undefined ? undefined : fs.openSync(dumpPath, "w");
    this.dumpBuf = [];
    this.dumpLen = 0;
  }

  error(text) {
    if (this.errors.length < MAX_ERRORS) this.errors.push(text);
    else if (this.errors.length === MAX_ERRORS) this.errors.push("(more errors left out)");
  }

  addSchema(s) {
    const old = this.schemas.get(s.id);
    if (old !== undefined && (old.name !== s.name || old.encoding !== s.encoding ||
                              Buffer.compare(old.data, s.data) !== 0)) {
      this.error(`schema id ${s.id} defined twice with different contents ('${old.name}', '${s.name}')`);
      return;
    }
    this.schemas.set(s.id, s);
  }

  addChannel(c) {
    this.channels.set(c.id, c);
    this.topic(c.topic, c);
  }

  topic(name, channel) {
    let t = this.topics.get(name);
    const schema = this.schemas.get(channel.schemaId);
    const schemaName = schema === undefined ? null : schema.name;
    if (t === undefined) {
      t = { schema: schemaName, count: 0, decoded: 0, errors: 0, first_error: null,
            first_log_time: null, last_log_time: null, encapsulation: {} };
      this.topics.set(name, t);
      t.channelIds = new Set();
    }
    if (!t.channelIds.has(channel.id)) {
      t.channelIds.add(channel.id);
      if (t.channelIds.size > 1 && t.schema !== schemaName) {
        this.error(`topic '${name}' is on several channels with different schemas ` +
          `('${t.schema}', '${schemaName}')`);
      }
    }
    return t;
  }

  // Returns null if messages of the channel can be decoded, else the reason.
  checkChannel(channel) {
    if (this.channelCheck.has(channel.id)) return this.channelCheck.get(channel.id);
    let problem = null;
    const schema = this.schemas.get(channel.schemaId);
    if (channel.schemaId === 0) {
      problem = `channel ${channel.id} ('${channel.topic}') has no schema`;
    } else if (schema === undefined) {
      problem = `channel ${channel.id} ('${channel.topic}') refers to unknown schema ${channel.schemaId}`;
    } else if (channel.messageEncoding !== "cdr") {
      problem = `channel ${channel.id} ('${channel.topic}') has message encoding ` +
        `'${channel.messageEncoding}', expected 'cdr'`;
    } else {
      let dec = this.decoders.get(schema.id);
      if (dec === undefined) {
        try {
          dec = new SchemaDecoder(schema);
        } catch (e) {
          dec = e instanceof Error ? e : new Error(String(e));
        }
        this.decoders.set(schema.id, dec);
      }
      if (dec instanceof Error) problem = dec.message;
    }
    if (problem !== null) this.error(problem);
    this.channelCheck.set(channel.id, problem);
    return problem;
  }

  onMessage(m) {
    const channel = this.channels.get(m.channelId);
    this.messages++;
    if (channel === undefined) {
      this.error(`message on unknown channel ${m.channelId}`);
      return;
    }
    this.perChannel.set(m.channelId, (this.perChannel.get(m.channelId) ?? 0) + 1);
    const t = this.topic(channel.topic, channel);
    t.count++;
    const lt = m.logTime;
    if (t.first_log_time === null) t.first_log_time = lt;
    t.last_log_time = lt;
    if (this.minLogTime === undefined || lt < this.minLogTime) this.minLogTime = lt;
    if (this.maxLogTime === undefined || lt > this.maxLogTime) this.maxLogTime = lt;
    if (m.data.byteLength >= 4) {
      const h = hex(m.data.subarray(0, 4));
      t.encapsulation[h] = (t.encapsulation[h] ?? 0) + 1;
    }
    let value;
    let problem = this.checkChannel(channel);
    if (problem === null) {
      try {
        value = this.decoders.get(channel.schemaId).decode(m.data);
      } catch (e) {
        problem = firstLine(e);
      }
    }
    if (problem === null) {
      t.decoded++;
      this.decoded++;
    } else {
      t.errors++;
      if (t.first_error === null) {
        t.first_error = `message ${t.count} (sequence ${m.sequence}, log_time ${lt}): ${problem}`;
      }
    }
    if (this.dumpFd !== undefined) {
      const line = JSON.stringify({
        topic: channel.topic,
        sequence: m.sequence,
        log_time: lt,
        publish_time: m.publishTime,
        data: value === undefined ? null : value,
        ...(problem === null ? {} : { error: problem }),
      }, jsonReplacer);
      this.dumpBuf.push(line);
      this.dumpLen += line.length;
      if (this.dumpLen > 1 << 20) this.flushDump();
    }
  }

  flushDump() {
    if (this.dumpFd === undefined || this.dumpBuf.length === 0) return;
    fs.writeSync(this.dumpFd, this.dumpBuf.join("\n") + "\n");
    this.dumpBuf = [];
    this.dumpLen = 0;
  }

  onMetadata(md) {
    this.metadataRecords++;
    if (Object.prototype.hasOwnProperty.call(this.metadata, md.name)) {
      this.extra.duplicate_metadata_names = [...(this.extra.duplicate_metadata_names ?? []), md.name];
    }
    this.metadata[md.name] = Object.fromEntries(md.metadata);
  }

  onChunk(compression) {
    this.chunks++;
    const key = compression === "" ? "none" : compression;
    this.compressions[key] = (this.compressions[key] ?? 0) + 1;
  }

  // Compares a Statistics record with what was read (only meaningful on a complete file).
  checkStatistics(stats, schemaCount, channelCount) {
    const want = (what, stated, seen) => {
      if (String(stated) !== String(seen)) {
        this.error(`statistics: ${what} is ${stated} but the file has ${seen}`);
      }
    };
    want("message_count", stats.messageCount, this.messages);
    want("schema_count", stats.schemaCount, schemaCount);
    want("channel_count", stats.channelCount, channelCount);
    want("chunk_count", stats.chunkCount, this.chunks);
    want("metadata_count", stats.metadataCount, this.metadataRecords);
    want("attachment_count", stats.attachmentCount, this.attachments);
    if (this.messages > 0) {
      want("message_start_time", stats.messageStartTime, this.minLogTime);
      want("message_end_time", stats.messageEndTime, this.maxLogTime);
    }
    const ids = new Set([...stats.channelMessageCounts.keys(), ...this.perChannel.keys()]);
    for (const id of ids) {
      const topic = this.channels.get(id)?.topic ?? "?";
      want(`channel_message_counts[${id}] ('${topic}')`,
        stats.channelMessageCounts.get(id) ?? 0n, this.perChannel.get(id) ?? 0);
    }
  }

  setStatistics(stats) {
    const counts = {};
    for (const [id, n] of stats.channelMessageCounts) counts[id] = Number(n);
    this.statistics = {
      message_count: Number(stats.messageCount),
      schema_count: stats.schemaCount,
      channel_count: stats.channelCount,
      attachment_count: stats.attachmentCount,
      metadata_count: stats.metadataCount,
      chunk_count: stats.chunkCount,
      message_start_time: stats.messageStartTime.toString(),
      message_end_time: stats.messageEndTime.toString(),
      channel_message_counts: counts,
    };
  }

  report() {
    this.flushDump();
    if (this.dumpFd !== undefined) fs.closeSync(this.dumpFd);
    const topics = {};
    for (const [name, t] of [...this.topics].sort(([a], [b]) => (a < b ? -1 : a > b ? 1 : 0))) {
      const { channelIds, ...rest } = t;
      topics[name] = {
        ...rest,
        first_log_time: t.first_log_time === null ? null : t.first_log_time.toString(),
        last_log_time: t.last_log_time === null ? null : t.last_log_time.toString(),
        channels: channelIds.size,
      };
      if (t.errors > 0) {
        this.error(`topic '${name}': ${t.errors} of ${t.count} messages failed: ${t.first_error}`);
      }
    }
    return {
      file: this.file,
      mode: this.mode,
      complete: this.complete,
      header: this.header,
      messages: this.messages,
      decoded: this.decoded,
      errors: this.errors,
      topics,
      metadata: this.metadata,
      statistics: this.statistics,
      chunks: { count: this.chunks, compression: this.compressions },
      attachments: this.attachments,
      order: this.mode === "streaming" ? "file" : "log_time",
      ...this.extra,
    };
  }
}

// CRC-32 of the file's bytes [0, end), read in pieces.
function fileCrc(fd, end) {
  let crc = crc32Init();
  const buf = Buffer.allocUnsafe(1 << 20);
  for (let pos = 0; pos < end;) {
    const n = fs.readSync(fd, buf, 0, Math.min(buf.length, end - pos), pos);
    if (n <= 0) throw new Error("file shrank while reading");
    crc = crc32Update(crc, buf.subarray(0, n));
    pos += n;
  }
  return crc32Final(crc);
}

function checkDataSectionCrc(check, fd, dataEndOffset, stated) {
  if (stated === undefined || stated === 0) {
    check.extra.data_section_crc = "absent";
    return;
  }
  const actual = fileCrc(fd, dataEndOffset);
  if (actual !== stated) {
    check.extra.data_section_crc = "mismatch";
    check.error(`data section CRC is ${actual} but DataEnd states ${stated}`);
  } else {
    check.extra.data_section_crc = "ok";
  }
}

async function readIndexed(file, fd, size, check, decompressHandlers) {
  const readable = {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const n = Number(length);
      const buf = new Uint8Array(n);
      const got = fs.readSync(fd, buf, 0, n, Number(offset));
      if (got !== n) throw new Error(`short read at offset ${offset}: ${got} of ${n} bytes`);
      return buf;
    },
  };
  let reader;
  try {
    reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  } catch (e) {
    check.error(`not a complete, indexed MCAP file (${firstLine(e)}); ` +
      "try --streaming to read what it holds");
    return;
  }
  check.complete = true;
  check.header = { profile: reader.header.profile, library: reader.header.library };
  for (const s of reader.schemasById.values()) check.addSchema(s);
  for (const c of reader.channelsById.values()) check.addChannel(c);
  for (const ci of [...reader.chunkIndexes].sort((a, b) =>
    a.chunkStartOffset < b.chunkStartOffset ? -1 : 1)) {
    check.onChunk(ci.compression);
  }
  try {
    for await (const m of reader.readMessages({ validateCrcs: true })) check.onMessage(m);
  } catch (e) {
    check.error(`reading messages failed after ${check.messages}: ${firstLine(e)}`);
  }
  try {
    for await (const md of reader.readMetadata()) check.onMetadata(md);
  } catch (e) {
    check.error(`reading metadata failed: ${firstLine(e)}`);
  }
  check.attachments = reader.attachmentIndexes.length;
  checkDataSectionCrc(check, fd, Number(reader.dataEndOffset), reader.dataSectionCrc);
  if (reader.statistics !== undefined) {
    check.setStatistics(reader.statistics);
    check.checkStatistics(reader.statistics, reader.schemasById.size, reader.channelsById.size);
  }
}

async function readStreaming(file, fd, size, check, decompressHandlers, pieceBytes) {
  const reader = new McapStreamReader({ includeChunks: true, decompressHandlers, validateCrcs: true });
  const buf = Buffer.allocUnsafe(pieceBytes);
  let appended = 0;
  let failed = false;
  let dataEnd;
  let footerSeen = false;
  const indexRecords = {};
  const schemaIds = new Set();
  const channelIds = new Set();
  const onRecord = (r) => {
    switch (r.type) {
      case "Header":
        check.header = { profile: r.profile, library: r.library };
        break;
      case "Schema":
        check.addSchema(r);
        schemaIds.add(r.id);
        break;
      case "Channel":
        check.addChannel(r);
        channelIds.add(r.id);
        break;
      case "Message":
        check.onMessage(r);
        break;
      case "Chunk":
        check.onChunk(r.compression);
        break;
      case "Metadata":
        check.onMetadata(r);
        break;
      case "Attachment":
        check.attachments++;
        break;
      case "Statistics":
        check.setStatistics(r);
        check.statsRecord = r;
        break;
      case "DataEnd":
        // DataEnd is 1 opcode byte + 8 length bytes + content; it ends where parsing stopped.
        dataEnd = { end: appended - reader.bytesRemaining(), crc: r.dataSectionCrc };
        break;
      case "Footer":
        footerSeen = true;
        break;
      default:
        indexRecords[r.type] = (indexRecords[r.type] ?? 0) + 1;
    }
  };
  for (let pos = 0; pos < size && !failed;) {
    const n = fs.readSync(fd, buf, 0, Math.min(pieceBytes, size - pos), pos);
    if (n <= 0) break;
    pos += n;
    try {
      reader.append(buf.subarray(0, n));
      appended += n;
      for (let r; (r = reader.nextRecord());) onRecord(r);
    } catch (e) {
      failed = true;
      check.error(`stopped at file byte ~${appended - reader.bytesRemaining()}: ${firstLine(e)}`);
    }
  }
  check.complete = !failed && reader.done() && footerSeen;
  check.extra.index_records = indexRecords;
  if (!check.complete && !failed) {
    check.extra.truncated_bytes = reader.bytesRemaining();
    check.extra.incomplete =
      `file ends without footer; ${reader.bytesRemaining()} bytes after the last complete record`;
  }
  if (check.complete) {
    if (dataEnd !== undefined) {
      // A DataEnd record is opcode 0x0F, a uint64 content length (4) and the uint32 CRC: 13 bytes
      // ending where the reader stopped after it.
      const rec = Buffer.alloc(13);
      const start = dataEnd.end - 13;
      if (start >= 0 && fs.readSync(fd, rec, 0, 13, start) === 13 && rec[0] === 0x0f &&
          rec.readBigUInt64LE(1) === 4n) {
        checkDataSectionCrc(check, fd, start, dataEnd.crc);
      } else {
        check.extra.data_section_crc = "unchecked (DataEnd record of unexpected length)";
      }
    }
    if (check.statsRecord !== undefined) {
      check.checkStatistics(check.statsRecord, schemaIds.size, channelIds.size);
    }
  }
  delete check.statsRecord;
}

async function main() {
  let opts;
  try {
    opts = parseArgs(process.argv.slice(2));
  } catch (e) {
    process.stderr.write(`mcap_check: ${e.message}\n${USAGE}\n`);
    return 2;
  }
  const file = opts.file;
  let fd;
  let size;
  try {
    fd = fs.openSync(file, "r");
    const st = fs.fstatSync(fd);
    if (!st.isFile()) throw new Error("not a regular file");
    size = st.size;
    const magic = Buffer.alloc(MCAP_MAGIC.length);
    const n = fs.readSync(fd, magic, 0, magic.length, 0);
    if (n === 0) throw new NotMcapError("the file is empty");
    if (Buffer.compare(magic.subarray(0, n), Buffer.from(MCAP_MAGIC).subarray(0, n)) !== 0) {
      throw new NotMcapError(`it does not start with the MCAP magic (first bytes: ` +
        `${magic.subarray(0, n).toString("hex")})`);
    }
    if (n < MCAP_MAGIC.length) {
      throw new NotMcapError(`only ${n} bytes, shorter than the MCAP magic`);
    }
  } catch (e) {
    const what = e instanceof NotMcapError ? "not an MCAP file" : "cannot read";
    process.stderr.write(`mcap_check: ${file}: ${what}: ${e.message}\n`);
    return 2;
  }
  const mode = opts.streaming ? "streaming" : "indexed";
  let check;
  try {
    check = new Check(file, mode, opts.dump);
  } catch (e) {
    process.stderr.write(`mcap_check: cannot write dump file ${opts.dump}: ${e.message}\n`);
    return 2;
  }
  const decompressHandlers = await loadDecompressHandlers();
  if (opts.streaming) {
    await readStreaming(file, fd, size, check, decompressHandlers, opts.pieceBytes);
  } else {
    await readIndexed(file, fd, size, check, decompressHandlers);
  }
  fs.closeSync(fd);
  const report = check.report();
  process.stdout.write(JSON.stringify(report, jsonReplacer, 1) + "\n");
  const ok = report.errors.length === 0 && report.decoded === report.messages &&
    (opts.streaming || report.complete);
  return ok ? 0 : 1;
}

main().then(
  (code) => { process.exitCode = code; },
  (e) => {
    process.stderr.write(`mcap_check: internal error: ${e?.stack ?? e}\n`);
    process.exitCode = 1;
  },
);
