// One WebSocket connection to a SweptCCD daemon (protocol sweptccd.v1,
// docs/WEBSOCKET.md) that reconnects by itself: the socket, the hello, the
// checks on every message, backoff (0.25 s doubling to 4 s) and the states.
// LiveClient (an avatar) and Viewer (a subscriber) build on it.

import { DecodeError, decodeServerMessage, encodeClientMessage, escapeForDisplay } from "./codec.js";
import { Emitter } from "./emitter.js";
import { ProofKind, SubtleLike, makeProof, parseKey } from "./proof.js";
import { DEFAULT_MAX_MESSAGE_BYTES, ErrorMessage, Hello, PROTOCOL_VERSION, Pong, SUBPROTOCOL, ServerMessage } from "./protocol.js";
import { RoomError, RoomResolver, doorUrl, helloRoomProblem, withRoom } from "./rooms.js";

/** What this library needs of a WebSocket (the browser's, or the `ws` package's). */
export interface SocketLike {
  readonly readyState: number;
  readonly bufferedAmount: number;
  readonly protocol: string;
  send(data: string): void;
  close(code?: number, reason?: string): void;
  onopen: ((ev: unknown) => void) | null;
  onmessage: ((ev: { data: unknown }) => void) | null;
  onclose: ((ev: { code: number; reason: string }) => void) | null;
  onerror: ((ev: unknown) => void) | null;
}
export type SocketFactory = (url: string, protocol: string) => SocketLike;

export interface ConnectionOptions {
  /** ws://host:port/ws or wss://host:port/ws (ignored with a resolver). */
  url?: string;
  /**
   * Room discovery (docs/DEPLOY.md): every connection asks the resolver for
   * `room`'s door, so a re-connection after a failover finds the new server.
   */
  resolver?: RoomResolver;
  /**
   * The room this client is for (with or without a resolver): sent as
   * `/ws?room=ROOM` and checked against hello.room; a door of another room
   * (409, or another hello.room) is refused and resolved again
   * (`wrongRooms`). "" or absent: any door.
   */
  room?: string;
  /** The key that proves this connection: 64 hex digits or 32 bytes; none: unsigned (lab bench) mode. */
  key?: string | Uint8Array;
  /** Default: the global WebSocket (browsers, Node 22+); in Node use "@sweptccd/client/node". */
  createSocket?: SocketFactory;
  /** Default: globalThis.crypto.subtle. */
  subtle?: SubtleLike;
  /** Reconnect (and join again) when the connection drops. Default true. */
  reconnect?: boolean;
  /** Backoff: first delay and cap, milliseconds (defaults 250 and 4000). */
  backoffInitialMs?: number;
  backoffMaxMs?: number;
  /** The largest message accepted; default 256 KiB (the server tells its own in hello.limits). */
  maxMessageBytes?: number;
  /** How long to wait for hello and for the answer to a join/subscribe, ms. Default 5000. */
  handshakeTimeoutMs?: number;
}

export type ConnectionState = "idle" | "connecting" | "handshake" | "ready" | "waiting" | "closed";

export interface CloseInfo {
  code: number;
  reason: string;
  /** Milliseconds until the next try; -1 when there will be none. */
  reconnectInMs: number;
}

export interface ConnectionEvents {
  state: ConnectionState;
  hello: Hello;
  /** An `error` frame from the server. */
  serverError: ErrorMessage;
  /** A frame this library refused (it is dropped; the connection goes on). */
  protocolError: string;
  close: CloseInfo;
  /** The answer to a keep-alive ping: its round trip and the server's clock. */
  pong: { pong: Pong; roundTripMs: number };
}

/** A failure that reconnecting cannot fix (a refused join, a wrong key, a replaced id). */
export class FatalError extends Error {
  constructor(
    message: string,
    readonly code: string,
  ) {
    super(message);
    this.name = "FatalError";
  }
}

/** Server error codes after which trying again is pointless (the others reconnect). */
const FINAL_CODES = new Set(["bad_proof", "replaced"]);

export abstract class Connection<E extends ConnectionEvents> extends Emitter<E> {
  protected readonly options: Required<
    Omit<ConnectionOptions, "key" | "createSocket" | "subtle" | "resolver" | "room">
  > & { key?: Uint8Array; createSocket: SocketFactory; subtle?: SubtleLike; resolver?: RoomResolver; room: string };
  protected socket: SocketLike | null = null;
  protected hello: Hello | null = null;
  private stateValue: ConnectionState = "idle";
  private delayMs: number;
  private timer: ReturnType<typeof setTimeout> | null = null;
  private handshakeTimer: ReturnType<typeof setTimeout> | null = null;
  private stopped = false;
  private readyWaiters: { resolve: () => void; reject: (e: Error) => void }[] = [];
  private keepAlive: ReturnType<typeof setInterval> | null = null;
  private lastSentMs = 0;
  /** Connections opened (the first and every reconnect). */
  connects = 0;
  /** Failover (docs/DEPLOY.md): events of another instance and hellos of an older one, dropped. */
  fencedEvents = 0;
  fencedHellos = 0;
  resolveFailures = 0;
  /** Doors of another room refused (a 409 to `?room=`, or another hello.room). */
  wrongRooms = 0;
  /** The newest daemon instance joined: a hello of an older one is fenced. */
  protected maxInstance = 0;
  /** The door of the current connection. */
  door = "";

  constructor(options: ConnectionOptions) {
    super();
    const createSocket =
      options.createSocket ??
      ((url: string, protocol: string) => {
        const WS = (globalThis as unknown as { WebSocket?: new (u: string, p: string) => SocketLike }).WebSocket;
        if (!WS) throw new Error("no global WebSocket: in Node, import from '@sweptccd/client/node'");
        return new WS(url, protocol);
      });
    if (!options.url && !options.resolver) throw new Error("give url, or resolver and room");
    withRoom("", options.room ?? "");  // A room name breaking the id rule: RoomError now.
    this.options = {
      url: options.url ?? "",
      resolver: options.resolver,
      room: options.room ?? "",
      key: options.key === undefined ? undefined : parseKey(options.key),
      createSocket,
      subtle: options.subtle ?? (globalThis as unknown as { crypto?: { subtle?: SubtleLike } }).crypto?.subtle,
      reconnect: options.reconnect ?? true,
      backoffInitialMs: options.backoffInitialMs ?? 250,
      backoffMaxMs: options.backoffMaxMs ?? 4000,
      maxMessageBytes: options.maxMessageBytes ?? DEFAULT_MAX_MESSAGE_BYTES,
      handshakeTimeoutMs: options.handshakeTimeoutMs ?? 5000,
    };
    this.delayMs = this.options.backoffInitialMs;
  }

  get state(): ConnectionState {
    return this.stateValue;
  }
  /** The server's hello of the current connection (instance, security, limits). */
  get serverHello(): Hello | null {
    return this.hello;
  }

  /**
   * Opens the connection; resolves once it is ready (joined, subscribed),
   * rejects on a FatalError or, without reconnect, when the first try fails.
   */
  connect(): Promise<void> {
    if (this.stopped) return Promise.reject(new Error("closed"));
    const p = new Promise<void>((resolve, reject) => this.readyWaiters.push({ resolve, reject }));
    if (this.stateValue === "idle") this.open();
    else if (this.stateValue === "ready") this.settle(null);
    return p;
  }

  /** Closes for good (no reconnect). */
  close(code = 1000, reason = "bye"): void {
    this.stopped = true;
    this.clearTimers();
    const s = this.socket;
    this.socket = null;
    if (s) {
      this.detach(s);
      try {
        s.close(code, reason);
      } catch {
        /* already closed */
      }
    }
    this.setState("closed");
    this.settle(new Error("closed"));
  }

  /** Sends one message; false when not open or over the cap. */
  protected sendMessage(message: object): boolean {
    const s = this.socket;
    if (!s || s.readyState !== 1) return false;
    let text: string;
    try {
      text = encodeClientMessage(message, this.maxBytes());
    } catch (e) {
      this.emit("protocolError", (e as Error).message);
      return false;
    }
    s.send(text);
    this.lastSentMs = Date.now();
    return true;
  }

  protected bufferedAmount(): number {
    return this.socket?.bufferedAmount ?? 0;
  }

  /** The proof for the current hello (security unsigned: ""). */
  protected async proof(kind: ProofKind, id: string): Promise<string> {
    const hello = this.hello!;
    if (hello.security !== "signed") return "";
    if (!this.options.key) throw new FatalError("the server is signed: give the room key (or this client's key)", "no_key");
    if (!this.options.subtle) throw new FatalError("no WebCrypto (crypto.subtle) to sign with: use https or localhost", "no_crypto");
    return makeProof(this.options.subtle, this.options.key, kind, hello.challenge, id);
  }

  /** After hello: send the join or the subscription. */
  protected abstract onHello(hello: Hello): Promise<void>;
  /** Every checked message after hello. */
  protected abstract onMessage(message: ServerMessage): void;
  /** The connection dropped (before a reconnect). */
  protected onDrop(): void {}

  /** The subclass reached its goal (joined, subscribed). */
  protected markReady(): void {
    this.clearHandshakeTimer();
    this.delayMs = this.options.backoffInitialMs;
    this.setState("ready");
    this.settle(null);
  }

  /** Gives up for good: the error goes to connect()'s promise. */
  protected fail(error: FatalError): void {
    this.emit("protocolError", error.message);
    this.settle(error);
    this.close(1000, error.code);
  }

  /** Drops this socket and reconnects (when allowed). */
  protected restart(reason: string): void {
    const s = this.socket;
    if (s) {
      try {
        s.close(4000, reason.slice(0, 100));
      } catch {
        /* closed */
      }
      this.dropped(4000, reason);
    }
  }

  private maxBytes(): number {
    const cap = this.hello?.limits?.max_message_bytes;
    return typeof cap === "number" && cap > 0 ? Math.min(cap, this.options.maxMessageBytes) : this.options.maxMessageBytes;
  }

  private open(): void {
    if (this.stopped) return;
    this.setState("connecting");
    this.hello = null;
    if (!this.options.resolver) {
      this.openUrl(withRoom(this.options.url, this.options.room));
      return;
    }
    this.options.resolver.resolve(this.options.room).then(
      (d) => {
        if (!this.stopped && this.stateValue === "connecting") this.openUrl(doorUrl(d, this.options.room));
      },
      (e) => {
        this.resolveFailures++;
        if (e instanceof RoomError && !e.retryable) {
          this.fail(new FatalError(e.message, "no_room"));
          return;
        }
        this.emit("protocolError", e instanceof Error ? e.message : String(e));
        this.dropped(4001, "room not resolved");
      },
    );
  }

  private openUrl(url: string): void {
    let s: SocketLike;
    this.door = url;
    try {
      s = this.options.createSocket(url, SUBPROTOCOL);
    } catch (e) {
      this.fail(new FatalError(`cannot open ${escapeForDisplay(url, 120)}: ${(e as Error).message}`, "bad_url"));
      return;
    }
    this.socket = s;
    this.connects++;
    this.armHandshakeTimer("no hello");
    s.onopen = () => {
      if (s.protocol && s.protocol !== SUBPROTOCOL) {
        this.fail(new FatalError(`server speaks "${escapeForDisplay(s.protocol, 40)}", not ${SUBPROTOCOL}`, "protocol"));
      }
      this.setState("handshake");
    };
    s.onmessage = (ev) => this.receive(s, ev.data);
    let refused = "";
    s.onerror = (ev) => {
      // onclose follows. Node's `ws` names a refused upgrade ("Unexpected
      // server response: 409": the door holds another room); a browser
      // tells nothing.
      const m = (ev as { message?: unknown } | null)?.message;
      if (typeof m === "string" && / 409$/.test(m)) refused = m;
    };
    s.onclose = (ev) => {
      if (this.socket !== s) return;
      if (refused && !this.hello) {
        this.wrongRooms++;
        this.emit("protocolError", `door ${escapeForDisplay(url, 120)} refused room '${this.options.room}' (409): it holds another room`);
      }
      this.dropped(ev.code, ev.reason);
    };
  }

  private receive(s: SocketLike, data: unknown): void {
    if (this.socket !== s) return;
    let msg: ServerMessage;
    try {
      msg = decodeServerMessage(data, this.options.maxMessageBytes);
    } catch (e) {
      this.emit("protocolError", e instanceof DecodeError ? e.message : String(e));
      return;
    }
    if (msg.type === "hello") {
      if (this.hello) {
        this.emit("protocolError", "a second hello: ignored");
        return;
      }
      if (msg.instance < this.maxInstance) {
        // A server of an older run of this room (a stale allocation): fenced.
        this.fencedHellos++;
        this.restart(`instance ${msg.instance} is older than instance ${this.maxInstance} joined already: fenced`);
        return;
      }
      const wrongRoom = helloRoomProblem(this.options.room, msg, this.door);
      if (wrongRoom) {
        this.wrongRooms++;  // Never joined: no event of another room is delivered.
        this.emit("protocolError", wrongRoom);
        this.restart(wrongRoom);
        return;
      }
      if (msg.protocol !== PROTOCOL_VERSION) {
        this.fail(new FatalError(`server protocol ${msg.protocol}, this client speaks ${PROTOCOL_VERSION}`, "protocol"));
        return;
      }
      this.hello = msg;
      this.startKeepAlive(msg);
      this.emit("hello", msg);
      this.armHandshakeTimer("no answer to the join/subscribe");
      this.onHello(msg).catch((e) => {
        if (e instanceof FatalError) this.fail(e);
        else this.restart(String(e));
      });
      return;
    }
    if (!this.hello) {
      this.emit("protocolError", `${msg.type} before hello: ignored`);
      return;
    }
    const instance = (msg as { instance?: unknown }).instance;
    if (msg.type !== "join_reply" && typeof instance === "number" && instance !== this.hello.instance) {
      this.fencedEvents++;  // An event of another daemon run (docs/WEBSOCKET.md, "The epoch").
      return;
    }
    if (msg.type === "pong") {
      this.emit("pong", { pong: msg, roundTripMs: msg.utime > 0 ? Date.now() - msg.utime / 1000 : NaN });
      return;
    }
    if (msg.type === "error") {
      this.emit("serverError", msg);
      if (FINAL_CODES.has(msg.code)) {
        this.fail(new FatalError(`server: ${msg.code}: ${escapeForDisplay(msg.message)}`, msg.code));
      }
      return;
    }
    this.onMessage(msg);
  }

  /**
   * The server closes a connection that sends nothing for idle_timeout_ms
   * (docs/WEBSOCKET.md section 3): a `ping` whenever nothing else was sent
   * for a third of it (a viewer, a paused avatar).
   */
  private startKeepAlive(hello: Hello): void {
    this.stopKeepAlive();
    const idle = hello.limits?.idle_timeout_ms;
    const periodMs = Math.max(100, (typeof idle === "number" && idle > 0 ? idle : 15000) / 3);
    this.lastSentMs = Date.now();
    this.keepAlive = setInterval(() => {
      if (Date.now() - this.lastSentMs >= periodMs * 0.9) this.sendMessage({ type: "ping", utime: Date.now() * 1000 });
    }, periodMs / 2);
  }

  private stopKeepAlive(): void {
    if (this.keepAlive) clearInterval(this.keepAlive);
    this.keepAlive = null;
  }

  private dropped(code: number, reason: string): void {
    const s = this.socket;
    if (s) this.detach(s);
    this.socket = null;
    this.stopKeepAlive();
    this.clearHandshakeTimer();
    this.onDrop();
    if (this.stopped) return;
    if (!this.options.reconnect) {
      this.emit("close", { code, reason, reconnectInMs: -1 });
      this.stopped = true;
      this.setState("closed");
      this.settle(new Error(`connection closed (${code}${reason ? " " + escapeForDisplay(reason, 80) : ""})`));
      return;
    }
    // 0.25 s doubling to 4 s, plus up to 25% jitter (docs/WEBSOCKET.md section 9).
    const delay = Math.round(this.delayMs * (1 + 0.25 * Math.random()));
    this.delayMs = Math.min(this.delayMs * 2, this.options.backoffMaxMs);
    this.emit("close", { code, reason, reconnectInMs: delay });
    this.setState("waiting");
    this.timer = setTimeout(() => {
      this.timer = null;
      this.open();
    }, delay);
  }

  private detach(s: SocketLike): void {
    s.onopen = s.onmessage = s.onclose = null;
    s.onerror = () => {};
  }

  private armHandshakeTimer(what: string): void {
    this.clearHandshakeTimer();
    this.handshakeTimer = setTimeout(() => {
      this.handshakeTimer = null;
      this.restart(`${what} within ${this.options.handshakeTimeoutMs} ms`);
    }, this.options.handshakeTimeoutMs);
  }

  private clearHandshakeTimer(): void {
    if (this.handshakeTimer) clearTimeout(this.handshakeTimer);
    this.handshakeTimer = null;
  }

  private clearTimers(): void {
    this.stopKeepAlive();
    this.clearHandshakeTimer();
    if (this.timer) clearTimeout(this.timer);
    this.timer = null;
  }

  private setState(state: ConnectionState): void {
    if (state === this.stateValue) return;
    this.stateValue = state;
    this.emit("state", state);
  }

  private settle(error: Error | null): void {
    const waiters = this.readyWaiters;
    this.readyWaiters = [];
    for (const w of waiters) {
      if (error) w.reject(error);
      else w.resolve();
    }
  }
}
