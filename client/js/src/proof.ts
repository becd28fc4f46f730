// The join proof of docs/WEBSOCKET.md: the connection proves that it holds a
// key (the room key for a live join or a subscription, a configured client's
// or object's key) by an HMAC-SHA256 over the server's one-time challenge:
//   proof = hex(HMAC-SHA256(key, LABEL + "\n" + challenge [+ "\n" + id]))
// (docs/WEBSOCKET.md section 4; a subscription has no id)
// with WebCrypto (crypto.subtle: browsers and Node 18+).

/** The labels of the proofs (the first line of the signed text). */
export const PROOF_LABEL = {
  join: "sweptccd-ws-v1 join",
  subscribe: "sweptccd-ws-v1 subscribe",
  object_attach: "sweptccd-ws-v1 object",
} as const;
export type ProofKind = keyof typeof PROOF_LABEL;

/** The part of WebCrypto's SubtleCrypto this module needs. */
export interface SubtleLike {
  importKey(
    format: "raw",
    keyData: Uint8Array,
    algorithm: { name: string; hash: string },
    extractable: boolean,
    usages: string[],
  ): Promise<unknown>;
  sign(algorithm: string, key: unknown, data: Uint8Array): Promise<ArrayBuffer>;
}

const HEX = /^[0-9a-fA-F]*$/;

/** Bytes of a hex string (even length, hex digits only); throws otherwise. */
export function hexToBytes(hex: string): Uint8Array {
  if (hex.length % 2 !== 0 || !HEX.test(hex)) throw new Error("not a hex string");
  const out = new Uint8Array(hex.length / 2);
  for (let i = 0; i < out.length; i++) out[i] = parseInt(hex.substr(2 * i, 2), 16);
  return out;
}

export function bytesToHex(bytes: Uint8Array): string {
  let s = "";
  for (const b of bytes) s += b.toString(16).padStart(2, "0");
  return s;
}

/**
 * A key as `sweptccd keygen` writes it (64 hex digits, surrounding white
 * space ignored), or its 32 bytes. Throws a one-line error otherwise.
 */
export function parseKey(key: string | Uint8Array): Uint8Array {
  if (typeof key !== "string") {
    if (key.length !== 32) throw new Error(`a key has 32 bytes, not ${key.length}`);
    return key;
  }
  const text = key.trim();
  if (text.length !== 64 || !HEX.test(text)) throw new Error("a key is 64 hex digits (sweptccd keygen)");
  return hexToBytes(text);
}

/** The text a proof signs. */
export function proofText(kind: ProofKind, challenge: string, id: string): string {
  return kind === "subscribe" ? `${PROOF_LABEL[kind]}\n${challenge}` : `${PROOF_LABEL[kind]}\n${challenge}\n${id}`;
}

/** hex(HMAC-SHA256(key, text)) */
export async function hmacHex(subtle: SubtleLike, key: Uint8Array, text: string): Promise<string> {
  const k = await subtle.importKey("raw", key, { name: "HMAC", hash: "SHA-256" }, false, ["sign"]);
  const mac = await subtle.sign("HMAC", k, new TextEncoder().encode(text));
  return bytesToHex(new Uint8Array(mac));
}

/** The proof for `kind` of `id` (a client id, an object id; ignored to subscribe). */
export function makeProof(
  subtle: SubtleLike,
  key: Uint8Array,
  kind: ProofKind,
  challenge: string,
  id: string,
): Promise<string> {
  return hmacHex(subtle, key, proofText(kind, challenge, id));
}
