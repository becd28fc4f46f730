// Node entry: LiveClient and Viewer with the `ws` package as the socket and
// node:crypto's WebCrypto (Node 18 has no global crypto.subtle).

import { webcrypto } from "node:crypto";
import WebSocket from "ws";
import type { ConnectionOptions, SocketFactory, SocketLike } from "./connection.js";
import { LiveClient, LiveClientOptions } from "./live_client.js";
import { Viewer } from "./viewer.js";
import { ObjectTracker, ObjectTrackerOptions } from "./object_tracker.js";
import { DEFAULT_MAX_MESSAGE_BYTES } from "./protocol.js";
import type { SubtleLike } from "./proof.js";

export * from "./index.js";

export interface NodeSocketOptions {
  /** Sent as the Origin header (a native client sends none). */
  origin?: string;
  /** PEM certificate(s) to trust for wss:// (e.g. a self-signed one). */
  ca?: string | Buffer;
  /** The largest frame accepted (default 256 KiB). */
  maxPayload?: number;
}

export function nodeSocketFactory(options: NodeSocketOptions = {}): SocketFactory {
  return (url: string, protocol: string) =>
    new WebSocket(url, [protocol], {
      origin: options.origin,
      ca: options.ca,
      maxPayload: options.maxPayload ?? DEFAULT_MAX_MESSAGE_BYTES,
      perMessageDeflate: false,
    }) as unknown as SocketLike;
}

export const nodeSubtle = webcrypto.subtle as unknown as SubtleLike;

function withNode<T extends ConnectionOptions>(o: T & NodeSocketOptions): T {
  return { subtle: nodeSubtle, createSocket: nodeSocketFactory(o), ...o };
}

export class NodeLiveClient extends LiveClient {
  constructor(options: LiveClientOptions & NodeSocketOptions) {
    super(withNode(options));
  }
}

export class NodeViewer extends Viewer {
  constructor(options: ConnectionOptions & NodeSocketOptions) {
    super(withNode(options));
  }
}

export class NodeObjectTracker extends ObjectTracker {
  constructor(options: ObjectTrackerOptions & NodeSocketOptions) {
    super(withNode(options));
  }
}
