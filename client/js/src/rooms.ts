// Room discovery (docs/DEPLOY.md, "Finding a room"), the same shape as the
// C++ client's room_resolver.h and Python's sweptccd.rooms: a room name
// resolved to its WebSocket door, through a static map (one host) or the
// Agones allocator's REST API (get-or-allocate by the sweptccd.dev/room
// label). Everything read is checked before use; failures are RoomError
// with one line.

import { escapeForDisplay } from "./codec.js";

const ROOM_NAME = /^[A-Za-z0-9_.-]{1,64}$/;
const HOST_NAME = /^[A-Za-z0-9.-]{1,253}$/;
const IPV6 = /^[0-9A-Fa-f:.]{2,45}$/;
const MAX_MAP_BYTES = 1 << 20;
const MAX_ROOMS = 4096;
const MAX_RESPONSE_BYTES = 64 << 10;

export class RoomError extends Error {
  /** retryable: the room may exist in a moment (no Ready server, allocator unreachable). */
  constructor(
    message: string,
    readonly retryable: boolean,
  ) {
    super(message);
    this.name = "RoomError";
  }
}

export interface DoorAddress {
  host: string;
  port: number;
  tls: boolean;
  /** "static" or "agones:GAMESERVER". */
  source: string;
}

export interface RoomResolver {
  resolve(room: string): Promise<DoorAddress>;
}

const show = (s: string) => `'${escapeForDisplay(String(s), 80)}'`;

/** The door's URL; with `room`, `/ws?room=ROOM` (withRoom). */
export function doorUrl(d: DoorAddress, room = ""): string {
  const host = d.host.includes(":") ? `[${d.host}]` : d.host;
  return withRoom(`${d.tls ? "wss" : "ws"}://${host}:${d.port}/ws`, room);
}

/**
 * `url` naming the room its client is for (docs/WEBSOCKET.md section 1):
 * `?room=ROOM` added, so a door of another room refuses the upgrade with 409
 * before any frame. `room` "" (no room): `url` as it is.
 */
export function withRoom(url: string, room: string): string {
  if (room === "") return url;
  checkRoom(room);
  return `${url}${url.includes("?") ? "&" : "?"}room=${room}`;
}

/**
 * The one check of a hello against the room the client is for
 * (docs/WEBSOCKET.md section 5, hello.room): "" when `room` is "" or the
 * hello names it; else one line, safe to print: a door of another room (a
 * room mix-up after a failover) whose events must never be delivered. A
 * hello without a string `room` is refused too.
 */
export function helloRoomProblem(room: string, hello: { room?: unknown }, door: string): string {
  if (room === "" || hello.room === room) return "";
  const held = typeof hello.room === "string" ? `holds room ${show(hello.room)}` : "does not say which room it holds";
  return `door ${show(door)} ${held}, not room ${show(room)}: refused (a room mix-up; resolving again)`;
}

function checkRoom(room: string): void {
  if (typeof room !== "string" || !ROOM_NAME.test(room)) {
    throw new RoomError(`room name ${show(room)} breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)`, false);
  }
}

function checkPort(text: string, url: string): number {
  if (!/^[0-9]{1,5}$/.test(text) || Number(text) < 1 || Number(text) > 65535) {
    throw new RoomError(`door address ${show(url)}: port is not 1-65535`, false);
  }
  return Number(text);
}

/** ws://HOST:PORT[/ws] or wss://...; HOST an IPv4 literal, [IPv6] or a DNS name. */
export function parseDoorUrl(url: string): DoorAddress {
  const m = /^(wss?):\/\/(.*?)(\/ws)?$/.exec(String(url));
  if (!m) throw new RoomError(`door address ${show(url)} is not ws://HOST:PORT or wss://HOST:PORT`, false);
  const rest = m[2];
  let host: string;
  let port: string;
  if (rest.startsWith("[")) {
    const close = rest.indexOf("]");
    if (close < 0 || rest[close + 1] !== ":") throw new RoomError(`door address ${show(url)}: expected [IPv6]:PORT`, false);
    host = rest.slice(1, close);
    port = rest.slice(close + 2);
    if (!IPV6.test(host) || !host.includes(":")) throw new RoomError(`door address ${show(url)}: bad IPv6`, false);
  } else {
    const colon = rest.lastIndexOf(":");
    if (colon < 0) throw new RoomError(`door address ${show(url)} has no :PORT`, false);
    host = rest.slice(0, colon);
    port = rest.slice(colon + 1);
    if (!HOST_NAME.test(host)) throw new RoomError(`door address ${show(url)}: host is not a name or an address`, false);
  }
  return { host, port: checkPort(port, url), tls: m[1] === "wss", source: "static" };
}

/** {"rooms": {"NAME": "wss://HOST:PORT", ...}}, at most 1 MiB and 4096 rooms. */
export class StaticRoomMap implements RoomResolver {
  private readonly rooms = new Map<string, DoorAddress>();

  static fromText(text: string, what = "room map"): StaticRoomMap {
    if (text.length > MAX_MAP_BYTES) throw new RoomError(`${what}: over ${MAX_MAP_BYTES} bytes`, false);
    let j: unknown;
    try {
      j = JSON.parse(text);
    } catch {
      j = null;
    }
    const rooms = (j as { rooms?: unknown } | null)?.rooms;
    if (!j || typeof j !== "object" || Array.isArray(j) || !rooms || typeof rooms !== "object" || Array.isArray(rooms)) {
      throw new RoomError(`${what}: not a JSON object with an object "rooms"`, false);
    }
    const entries = Object.entries(rooms as Record<string, unknown>);
    if (entries.length > MAX_ROOMS) throw new RoomError(`${what}: more than ${MAX_ROOMS} rooms`, false);
    const map = new StaticRoomMap();
    for (const [name, url] of entries) {
      checkRoom(name);
      if (typeof url !== "string") throw new RoomError(`${what}: room ${show(name)} is not a string`, false);
      map.rooms.set(name, parseDoorUrl(url));
    }
    return map;
  }

  get size(): number {
    return this.rooms.size;
  }

  async resolve(room: string): Promise<DoorAddress> {
    checkRoom(room);
    const d = this.rooms.get(room);
    if (!d) throw new RoomError(`room ${show(room)} is not in the room map`, false);
    return { ...d };
  }
}

export interface AgonesAllocatorOptions {
  /** https://HOST[:PORT] of the allocator service (or of a gateway in front of it). */
  url: string;
  namespace?: string;
  roomLabel?: string;
  /** Labels of the fleet to allocate a new room from, e.g. {"sweptccd.dev/scene": "dragon"}. */
  fleetLabels: Record<string, string>;
  portName?: string;
  doorTls?: boolean;
  timeoutMs?: number;
  /** Default: the global fetch (browsers, Node 18+). mTLS: a fetch with the client certificate. */
  fetch?: (url: string, init: { method: string; headers: Record<string, string>; body: string; signal: AbortSignal }) => Promise<{ status: number; text(): Promise<string> }>;
}

type Required2 = Required<Omit<AgonesAllocatorOptions, "fetch">> & Pick<AgonesAllocatorOptions, "fetch">;

export class AgonesAllocatorResolver implements RoomResolver {
  readonly options: Required2;

  constructor(options: AgonesAllocatorOptions) {
    if (!/^https?:\/\//.test(String(options.url))) {
      throw new RoomError(`allocator URL ${show(options.url)} is not https://HOST[:PORT]`, false);
    }
    if (!options.fleetLabels || Object.keys(options.fleetLabels).length === 0) {
      throw new RoomError("allocator: no fleet label to allocate a new room from (e.g. sweptccd.dev/scene=NAME)", false);
    }
    this.options = {
      url: options.url.replace(/\/+$/, ""),
      namespace: options.namespace ?? "default",
      roomLabel: options.roomLabel ?? "sweptccd.dev/room",
      fleetLabels: { ...options.fleetLabels },
      portName: options.portName ?? "websocket",
      doorTls: options.doorTls ?? true,
      timeoutMs: options.timeoutMs ?? 2000,
      fetch: options.fetch,
    };
  }

  /** The request body (Agones allocation.proto): get the room's server, else allocate one. */
  requestBody(room: string): object {
    const roomLabels = { [this.options.roomLabel]: room };
    return {
      namespace: this.options.namespace,
      gameServerSelectors: [
        { matchLabels: roomLabels, gameServerState: "ALLOCATED" },
        { matchLabels: this.options.fleetLabels, gameServerState: "READY" },
      ],
      metadata: { labels: roomLabels },
    };
  }

  /** The door out of an AllocationResponse (checked). */
  parseResponse(body: string): DoorAddress {
    if (body.length > MAX_RESPONSE_BYTES) throw new RoomError("allocator: answer too long", true);
    let j: Record<string, unknown>;
    try {
      j = JSON.parse(body);
    } catch {
      throw new RoomError("allocator: answer is not JSON", true);
    }
    if (!j || typeof j !== "object" || Array.isArray(j)) throw new RoomError("allocator: answer is not JSON", true);
    const host = typeof j.address === "string" ? j.address : "";
    if (!HOST_NAME.test(host) && !(IPV6.test(host) && host.includes(":"))) {
      throw new RoomError(`allocator: answer's address ${show(host)} is not a host`, true);
    }
    if (!Array.isArray(j.ports) || j.ports.length > 64) throw new RoomError("allocator: answer has no ports", true);
    let port = 0;
    for (const p of j.ports as unknown[]) {
      const q = p as { name?: unknown; port?: unknown };
      if (!q || typeof q !== "object" || q.name !== this.options.portName) continue;
      if (!Number.isInteger(q.port) || (q.port as number) < 1 || (q.port as number) > 65535) {
        throw new RoomError(`allocator: port ${show(this.options.portName)} is not 1-65535`, true);
      }
      port = q.port as number;
    }
    if (!port) throw new RoomError(`allocator: answer has no port named ${show(this.options.portName)}`, true);
    const name = typeof j.gameServerName === "string" ? j.gameServerName : "";
    return { host, port, tls: this.options.doorTls, source: `agones:${escapeForDisplay(name, 64)}` };
  }

  async resolve(room: string): Promise<DoorAddress> {
    checkRoom(room);
    const f = this.options.fetch ?? (globalThis as unknown as { fetch: Required2["fetch"] }).fetch;
    if (!f) throw new RoomError("allocator: no fetch (Node 18+ or a browser)", false);
    const abort = new AbortController();
    const timer = setTimeout(() => abort.abort(), this.options.timeoutMs);
    let status: number;
    let text: string;
    try {
      const r = await f(`${this.options.url}/gameserverallocation`, {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify(this.requestBody(room)),
        signal: abort.signal,
      });
      status = r.status;
      text = await r.text();
    } catch (e) {
      throw new RoomError(`allocator ${show(this.options.url)}: ${escapeForDisplay(String((e as Error).message), 120)}`, true);
    } finally {
      clearTimeout(timer);
    }
    if (status === 429) throw new RoomError(`allocator: no room server Ready for ${show(room)} (429); retry`, true);
    if (status !== 200) {
      throw new RoomError(`allocator: HTTP ${status} for ${show(room)}: ${escapeForDisplay(text, 160)}`, status >= 500);
    }
    return this.parseResponse(text);
  }
}
