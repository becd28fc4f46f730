// Encoding what a client sends and decoding (with checks) what a server sends.
// Everything from the network is hostile: the size is checked before the
// text is parsed, the shape before a field is used.

import { DEFAULT_MAX_MESSAGE_BYTES, SERVER_TYPES, ServerMessage } from "./protocol.js";

export class DecodeError extends Error {
  constructor(message: string) {
    super(message);
    this.name = "DecodeError";
  }
}

/** A string safe to print on one line: controls escaped, at most `max` chars. */
export function escapeForDisplay(text: string, max = 200): string {
  let out = "";
  for (const ch of text.slice(0, max)) {
    const c = ch.codePointAt(0)!;
    if (c < 0x20 || c === 0x7f || (c >= 0x80 && c < 0xa0) || c === 0x2028 || c === 0x2029) {
      out += "\\x" + c.toString(16).padStart(2, "0");
    } else if (ch === "\\") {
      out += "\\\\";
    } else {
      out += ch;
    }
  }
  return text.length > max ? out + "..." : out;
}

function isNum(v: unknown): v is number {
  return typeof v === "number" && Number.isFinite(v);
}

const REQUIRED: Record<string, Record<string, "number" | "string" | "array" | "boolean">> = {
  hello: { protocol: "number", instance: "number", security: "string", challenge: "string" },
  join_reply: { client_id: "string", reason: "number", message: "string", session: "number", instance: "number" },
  contact_event: { client_id: "string", seq0: "number", seq1: "number", pair: "number", result: "number", contacts: "array" },
  shared_contact: { client_id: "string", pair: "number", entries: "array" },
  rejection: { client_id: "string", seq: "number", reason: "string", message: "string" },
  status: { instance: "number", client_id: "array" },
  room: { clients: "array" },
  tracker_pose: { client_id: "string", seq: "number", position: "array", orientation: "array" },
  object_pose: { object_id: "string", position: "array", orientation: "array" },
  error: { code: "string", message: "string" },
  object_attach_reply: { object_id: "string", ok: "boolean" },
  pong: { utime: "number", server_utime: "number" },
};

/**
 * One server message from the text of one WebSocket frame. Throws
 * DecodeError (one line) for anything that is not a known, well-formed one.
 */
export function decodeServerMessage(text: unknown, maxBytes = DEFAULT_MAX_MESSAGE_BYTES): ServerMessage {
  if (typeof text !== "string") throw new DecodeError("binary frame (protocol sweptccd.v1 sends text frames only)");
  // UTF-16 length <= UTF-8 bytes * 1; a string longer than the cap in code
  // units is certainly over it in bytes.
  if (text.length > maxBytes) throw new DecodeError(`message of ${text.length} characters over the cap of ${maxBytes} bytes`);
  let value: unknown;
  try {
    value = JSON.parse(text);
  } catch (e) {
    throw new DecodeError(`not JSON: ${escapeForDisplay(String((e as Error).message), 80)}`);
  }
  if (typeof value !== "object" || value === null || Array.isArray(value)) throw new DecodeError("not a JSON object");
  const msg = value as Record<string, unknown>;
  if (typeof msg.type !== "string") throw new DecodeError('no "type" string');
  if (!SERVER_TYPES.has(msg.type)) throw new DecodeError(`unknown type "${escapeForDisplay(msg.type, 40)}"`);
  const fields = REQUIRED[msg.type] ?? {};
  for (const [name, kind] of Object.entries(fields)) {
    const v = msg[name];
    const ok =
      kind === "number" ? isNum(v) : kind === "array" ? Array.isArray(v) : kind === "boolean" ? typeof v === "boolean" : typeof v === "string";
    if (!ok) throw new DecodeError(`${msg.type}: field "${name}" missing or not a ${kind}`);
  }
  if (msg.type === "hello" && !/^[0-9a-f]{64}$/.test(msg.challenge as string)) {
    throw new DecodeError("hello: challenge is not 64 lower-case hex digits");
  }
  return msg as unknown as ServerMessage;
}

/** The text of one frame a client sends (throws when over the cap). */
export function encodeClientMessage(message: object, maxBytes = DEFAULT_MAX_MESSAGE_BYTES): string {
  const text = JSON.stringify(message);
  if (text.length > maxBytes) throw new Error(`message of ${text.length} bytes over the cap of ${maxBytes}`);
  return text;
}
