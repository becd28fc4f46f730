// The display meshes of GET /scene/N.bin (docs/WEBSOCKET.md section 8),
// little-endian: "SCM1", uint32 V, uint32 T, uint32 0, float32[3V]
// positions, uint32[3T] indices. Checked before anything is allocated: the
// byte count must be exactly what V and T say, every index below V, every
// position finite.

export interface SceneMeshData {
  positions: Float32Array;
  indices: Uint32Array;
}

/** Vertex and triangle caps (the server's max_triangles is 200000 over the whole scene). */
export const MAX_SCENE_VERTICES = 4_000_000;
export const MAX_SCENE_TRIANGLES = 4_000_000;

export function parseSceneMesh(buffer: ArrayBuffer): SceneMeshData {
  if (buffer.byteLength < 16) throw new Error(`scene mesh: ${buffer.byteLength} bytes, shorter than its 16-byte header`);
  const view = new DataView(buffer);
  const magic = String.fromCharCode(view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
  if (magic !== "SCM1") throw new Error("scene mesh: no SCM1 magic");
  const v = view.getUint32(4, true);
  const t = view.getUint32(8, true);
  if (view.getUint32(12, true) !== 0) throw new Error("scene mesh: reserved field not 0");
  if (v > MAX_SCENE_VERTICES || t > MAX_SCENE_TRIANGLES) throw new Error(`scene mesh: ${v} vertices / ${t} triangles over the caps`);
  const want = 16 + 12 * v + 12 * t;
  if (buffer.byteLength !== want) throw new Error(`scene mesh: ${buffer.byteLength} bytes, header says ${want}`);
  const positions = new Float32Array(3 * v);
  for (let i = 0; i < 3 * v; i++) {
    const x = view.getFloat32(16 + 4 * i, true);
    if (!Number.isFinite(x)) throw new Error(`scene mesh: position ${Math.floor(i / 3)} not finite`);
    positions[i] = x;
  }
  const indices = new Uint32Array(3 * t);
  const base = 16 + 12 * v;
  for (let i = 0; i < 3 * t; i++) {
    const k = view.getUint32(base + 4 * i, true);
    if (k >= v) throw new Error(`scene mesh: triangle ${Math.floor(i / 3)} index ${k} >= ${v} vertices`);
    indices[i] = k;
  }
  return { positions, indices };
}
