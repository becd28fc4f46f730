// The messages of protocol sweptccd.v1 (docs/WEBSOCKET.md): JSON objects that
// mirror the LCM types of msgs/*.lcm field for field (same names, units and
// meanings). Only the fields a client relies on are typed strictly; every
// message may carry more (a newer server), which are kept as they are.

/** The WebSocket subprotocol a client asks for (Sec-WebSocket-Protocol). */
export const SUBPROTOCOL = "sweptccd.v1";
/** The protocol version this library speaks (hello.protocol). */
export const PROTOCOL_VERSION = 1;
/** The largest message this library sends or accepts (the server's default cap). */
export const DEFAULT_MAX_MESSAGE_BYTES = 256 * 1024;

/** join_reply_t.REASON_* codes. */
export const REASON = {
  ACCEPTED: 0,
  BAD_SKELETON: 1,
  ID_IN_USE: 2,
  TOO_MANY_CLIENTS: 3,
  TOO_MANY_LINKS: 4,
  BAD_CLIENT_ID: 5,
  BAD_FILTER: 6,
  BAD_OPTIONS: 7,
  BUSY: 8,
  STALE_REQUEST: 9,
  JOINS_DISABLED: 10,
} as const;

/** contact_event_t.RESULT_* and shared_entry_t.RESULT_*. */
export const RESULT = { FREE: 0, CONTACT: 1, INVALID: 2 } as const;
/** join_request_t.MOTION_*. */
export const MOTION = { ARTICULATED: 0, INDEPENDENT: 1 } as const;

export type Vec3 = [number, number, number];
export type Quat = [number, number, number, number]; // [w, x, y, z]

export interface Limits {
  [name: string]: number;
}

export interface Hello {
  type: "hello";
  protocol: number;
  instance: number;
  security: "signed" | "unsigned";
  challenge: string;
  server_utime: number;
  shared_world?: boolean;
  /** The room the door holds (the client checks it: rooms.ts helloRoomProblem). */
  room?: string;
  limits?: Limits;
}

/** The skeleton arrays of a join request (SPEC section 1, link i at index i). */
export interface SkeletonArrays {
  link_name: string[];
  parent: number[];
  a: Vec3[];
  b: Vec3[];
  radius: number[];
}

export interface EntityIgnore {
  link: string;
  entity: string;
  other_link?: string;
}

export interface JoinRequest extends SkeletonArrays {
  type: "join_request";
  utime: number;
  client_id: string;
  nonce: number;
  motion: number;
  eps_s: number;
  delta_m: number;
  ignore: string[];
  ignore_entity_link: string[];
  ignore_entity: string[];
  ignore_entity_other_link: string[];
  proof: string;
}

export interface JoinReply {
  type: "join_reply";
  utime: number;
  client_id: string;
  nonce: number;
  reason: number;
  reason_name?: string;
  message: string;
  session: number;
  instance: number;
  silence_timeout_ms: number;
}

export interface TrackerPose {
  type: "tracker_pose";
  utime: number;
  client_id: string;
  session: number;
  seq: number;
  position: Vec3[];
  orientation: Quat[];
}

export interface ObjectPose {
  type: "object_pose";
  utime: number;
  object_id: string;
  session: number;
  seq: number;
  position: Vec3;
  orientation: Quat;
}

export interface ContactRecord {
  link: number;
  object: number;
  triangle: number;
  s: number;
  point_link: Vec3;
  point_env: Vec3;
  normal: Vec3;
  separation: number;
}

export interface LinkBracket {
  link: number;
  s_lo: number;
  s_hi: number;
  t_lo: number;
  t_hi: number;
  initially_colliding: boolean;
  undecided: boolean;
  has_witness: boolean;
  witness: ContactRecord;
}

export interface ContactEvent {
  type: "contact_event";
  utime: number;
  client_id: string;
  seq0: number;
  seq1: number;
  pair: number;
  utime0: number;
  utime1: number;
  result: number;
  result_name?: string;
  error: string;
  initially_colliding: boolean;
  undecided: boolean;
  s_lo: number;
  s_hi: number;
  t_lo: number;
  t_hi: number;
  contacts: ContactRecord[];
  links: LinkBracket[];
  receive_utime: number;
  compute_us: number;
  queue_us: number;
  skipped_pairs_total: number;
}

export interface EntityContact {
  link: number;
  other_link: number;
  triangle: number;
  s: number;
  point_link: Vec3;
  point_other: Vec3;
  normal: Vec3;
  separation: number;
}

export interface SharedEntry {
  entity: string;
  entity_kind: number;
  t_from: number;
  t_to: number;
  result: number;
  result_name?: string;
  error: string;
  initially_colliding: boolean;
  undecided: boolean;
  s_lo: number;
  s_hi: number;
  t_lo: number;
  t_hi: number;
  contacts: EntityContact[];
  links: unknown[];
  waited_us: number;
  ended_by_timeout: boolean;
  compute_us: number;
  queue_us: number;
}

export interface SharedContact {
  type: "shared_contact";
  utime: number;
  client_id: string;
  seq0: number;
  seq1: number;
  pair: number;
  utime0: number;
  utime1: number;
  receive_utime: number;
  entries: SharedEntry[];
}

export interface Rejection {
  type: "rejection";
  utime: number;
  client_id: string;
  seq: number;
  reason: string;
  message: string;
  suppressed: number;
}

export interface Status {
  type: "status";
  utime: number;
  backend: string;
  renderer: string;
  security: string;
  client_id: string[];
  poses_received: number[];
  pairs_answered: number[];
  pairs_skipped: number[];
  rejected: number[];
  seq_gaps: number[];
  rate_limited: number[];
  latency_median_us: number[];
  latency_p99_us: number[];
  queue_depth: number;
  instance: number;
  [more: string]: unknown;
}

/** A joined client of a `room` snapshot: its id and skeleton. */
export interface RoomClient extends Partial<SkeletonArrays> {
  client_id: string;
  [more: string]: unknown;
}

export interface RoomObject {
  object_id: string;
  /** Its mesh in scene.json (in its own frame). */
  scene_index: number;
}

export interface Room {
  type: "room";
  utime?: number;
  instance?: number;
  shared_world?: boolean;
  clients: RoomClient[];
  objects: RoomObject[];
  /** The static objects' names in index order (= scene.json indices 0..E-1). */
  environment: string[];
  [more: string]: unknown;
}

/** GET /scene.json (docs/WEBSOCKET.md section 8). */
export interface SceneMesh {
  index: number;
  kind: "environment" | "object";
  name: string;
  object_id?: string;
  triangles: number;
  source_triangles: number;
  vertices: number;
  url: string;
  min: Vec3;
  max: Vec3;
}
export interface SceneDescription {
  max_triangles: number;
  meshes: SceneMesh[];
}

export interface ErrorMessage {
  type: "error";
  code: string;
  message: string;
  /** A fatal error is followed by a close frame. */
  fatal?: boolean;
}

export interface ObjectAttachReply {
  type: "object_attach_reply";
  object_id: string;
  ok: boolean;
  message: string;
}

/** The answer to a `ping` (docs/WEBSOCKET.md section 5). */
export interface Pong {
  type: "pong";
  utime: number;
  server_utime: number;
}

/** Every message a server sends that this library knows. */
export type ServerMessage =
  | Hello
  | JoinReply
  | ContactEvent
  | SharedContact
  | Rejection
  | Status
  | Room
  | TrackerPose
  | ObjectPose
  | ErrorMessage
  | ObjectAttachReply
  | Pong;

/** The message types a server may send (anything else is refused by decode). */
export const SERVER_TYPES: ReadonlySet<string> = new Set([
  "hello",
  "join_reply",
  "contact_event",
  "shared_contact",
  "rejection",
  "status",
  "room",
  "tracker_pose",
  "object_pose",
  "error",
  "object_attach_reply",
  "pong",
]);
