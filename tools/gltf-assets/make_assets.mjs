// Builds relight's textured glTF test assets with third-party tools, and validates each with the
// Khronos glTF-Validator. Driven by relight-testdata (`gltf_assets()`); runnable by hand:
//
//   node make_assets.mjs build --npm DIR --obj spot.obj --texture spot_texture.png --out OUT
//   node make_assets.mjs validate --npm DIR FILE.glb|FILE.gltf ...
//
// `--npm DIR` is the folder scripts/setup.sh installed the tools into (package.json and
// package-lock.json beside this script pin them): obj2gltf, @gltf-transform/core and
// @gltf-transform/extensions (the library under @gltf-transform/cli), gltf-validator.
//
// `build` writes into OUT (which it creates; it must not exist yet):
//   spot.obj, spot.mtl, spot_texture.png   obj2gltf's input: the OBJ with an `mtllib` line, an
//                                          MTL whose map_Kd names the copied texture
//   spot.glb            obj2gltf: base-colour texture embedded, metallic 0, roughness 0.5
//   spot_mr.glb         + a metallic-roughness texture: vertical stripes (u), roughness (G)
//                         0.2 / 0.9 in 8 stripes, metallic (B) 0 / 1 in 4 stripes; factors 1
//   spot_normal.glb     + a normal texture: 8 x 8 bumps of a height field sin(2 pi 8 u) sin(2 pi
//                         8 v), tangent-space, scale 1
//   spot_transform.glb  KHR_texture_transform on the base colour: offset (0.25, 0), rotation
//                         0, scale (2, 2)
//   spot_external.gltf  base colour + metallic-roughness + normal, with a separate .bin and
//                         .png files (spot_external.bin, spot_external_*.png)
//   spot_two.glb        two nodes, `spot_plastic` at the origin and `spot_metal` moved by 1.5
//                         bounding-box widths along +x, each its own mesh and material
//                         (`spot_plastic`: metallic 0, roughness 0.5; `spot_metal`: metallic 1,
//                         roughness 0.3), sharing accessors
//   validation.tsv      per asset: file, errors, warnings, infos, hints, issue codes
//   timings.tsv         per step: name, milliseconds
// Every asset must have 0 validator errors, else the script prints the messages and exits 1.
// Generated maps are 64 x 64 8-bit RGB PNGs, written by the small encoder below.

import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';

function usage(msg) {
  console.error(`make_assets: ${msg}`);
  console.error('usage: node make_assets.mjs build --npm DIR --obj OBJ --texture PNG --out OUT');
  console.error('       node make_assets.mjs validate --npm DIR FILE...');
  process.exit(2);
}

function parseArgs(argv) {
  const [cmd, ...rest] = argv;
  const opts = { files: [] };
  for (let i = 0; i < rest.length; i++) {
    const a = rest[i];
    if (a.startsWith('--')) {
      if (i + 1 >= rest.length) usage(`${a} needs a value`);
      opts[a.slice(2)] = rest[++i];
    } else {
      opts.files.push(a);
    }
  }
  if (!opts.npm) usage('--npm DIR is required');
  return { cmd, opts };
}

// The tools, loaded from the folder setup.sh installed them into.
function loadTools(npmDir) {
  const manifest = path.join(path.resolve(npmDir), 'package.json');
  if (!fs.existsSync(manifest)) {
    console.error(`make_assets: no npm tools at ${npmDir} (run scripts/setup.sh)`);
    process.exit(3);
  }
  const require = createRequire(manifest);
  return {
    obj2gltf: require('obj2gltf'),
    core: require('@gltf-transform/core'),
    extensions: require('@gltf-transform/extensions'),
    validator: require('gltf-validator'),
  };
}

// ---- PNG encoding (8-bit RGB, one IDAT, filter 0 on every row) ----

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

function crc32(bytes) {
  let c = 0xffffffff;
  for (const b of bytes) c = CRC_TABLE[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

function chunk(type, data) {
  const out = Buffer.alloc(12 + data.length);
  out.writeUInt32BE(data.length, 0);
  out.write(type, 4, 'latin1');
  data.copy(out, 8);
  out.writeUInt32BE(crc32(out.subarray(4, 8 + data.length)), 8 + data.length);
  return out;
}

/** PNG bytes of a `w` x `h` RGB image given by `texel(x, y) -> [r, g, b]` in 0..=255. */
function encodePng(w, h, texel) {
  const raw = Buffer.alloc(h * (1 + 3 * w));
  for (let y = 0; y < h; y++) {
    const row = y * (1 + 3 * w);
    raw[row] = 0;
    for (let x = 0; x < w; x++) {
      const [r, g, b] = texel(x, y);
      raw[row + 1 + 3 * x] = r;
      raw[row + 2 + 3 * x] = g;
      raw[row + 3 + 3 * x] = b;
    }
  }
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(w, 0);
  ihdr.writeUInt32BE(h, 4);
  ihdr.set([8, 2, 0, 0, 0], 8); // bit depth 8, colour type RGB, deflate, filter 0, no interlace
  const signature = Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
  return Buffer.concat([
    signature,
    chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw)),
    chunk('IEND', Buffer.alloc(0)),
  ]);
}

const MAP_SIZE = 64;

// Metallic-roughness: R unused (255), G = roughness, B = metallic, in stripes along u.
function metallicRoughnessPng() {
  return encodePng(MAP_SIZE, MAP_SIZE, (x) => {
    const rough = Math.floor((8 * x) / MAP_SIZE) % 2 === 0 ? 51 : 230; // 0.2, 0.9
    const metal = Math.floor((4 * x) / MAP_SIZE) % 2 === 0 ? 0 : 255;
    return [255, rough, metal];
  });
}

// Tangent-space normals of the height field a sin(2 pi k u) sin(2 pi k v), k = 8.
function normalPng() {
  const k = 8;
  const a = 0.02;
  const w = 2 * Math.PI * k;
  return encodePng(MAP_SIZE, MAP_SIZE, (x, y) => {
    const u = (x + 0.5) / MAP_SIZE;
    const v = (y + 0.5) / MAP_SIZE;
    const dhdu = a * w * Math.cos(w * u) * Math.sin(w * v);
    const dhdv = a * w * Math.sin(w * u) * Math.cos(w * v);
    const len = Math.hypot(dhdu, dhdv, 1);
    const enc = (c) => Math.round((0.5 * (c / len) + 0.5) * 255);
    return [enc(-dhdu), enc(-dhdv), enc(1)];
  });
}

// ---- validation ----

/** The validator's report of `file` (external resources read from its folder). */
async function validate(validator, file) {
  const dir = path.dirname(path.resolve(file));
  return validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        const p = path.resolve(dir, decodeURIComponent(uri));
        fs.readFile(p, (err, data) => (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
      }),
  });
}

function verdictLine(file, report) {
  const i = report.issues;
  const codes = [...new Set(i.messages.map((m) => m.code))].join(',');
  return [path.basename(file), i.numErrors, i.numWarnings, i.numInfos, i.numHints, codes].join('\t');
}

function errorMessages(file, report) {
  return report.issues.messages
    .filter((m) => m.severity === 0)
    .map((m) => `${file}: ${m.code} at ${m.pointer ?? '(asset)'}: ${m.message}`);
}

async function validateFiles(tools, files) {
  if (files.length === 0) usage('validate needs at least one file');
  let failed = false;
  for (const file of files) {
    let report;
    try {
      report = await validate(tools.validator, file);
    } catch (e) {
      console.error(`${file}: the validator could not read it: ${e}`);
      failed = true;
      continue;
    }
    console.log(verdictLine(file, report));
    const errors = errorMessages(file, report);
    errors.forEach((m) => console.error(m));
    failed ||= errors.length > 0;
  }
  process.exit(failed ? 1 : 0);
}

// ---- building ----

async function build(tools, opts) {
  for (const k of ['obj', 'texture', 'out']) if (!opts[k]) usage(`build needs --${k}`);
  const out = path.resolve(opts.out);
  if (fs.existsSync(out)) usage(`${out} exists already`);
  fs.mkdirSync(out, { recursive: true });
  const timings = [];
  const step = async (name, f) => {
    const t0 = process.hrtime.bigint();
    const r = await f();
    const ms = Number(process.hrtime.bigint() - t0) / 1e6;
    timings.push(`${name}\t${ms.toFixed(1)}`);
    console.log(`make_assets: ${name}: ${ms.toFixed(0)} ms`);
    return r;
  };
  const outPath = (f) => path.join(out, f);

  // obj2gltf's input: the OBJ naming an MTL that names the texture, all in OUT.
  await step('inputs', () => {
    const obj = fs.readFileSync(opts.obj, 'utf8');
    if (/^\s*mtllib\s/m.test(obj)) throw new Error(`${opts.obj} has an mtllib line already`);
    fs.writeFileSync(outPath('spot.obj'), `mtllib spot.mtl\nusemtl spot\n${obj}`);
    fs.copyFileSync(opts.texture, outPath('spot_texture.png'));
    // With metallicRoughness: Kd = base colour, Ks = metallic, Ns = roughness.
    fs.writeFileSync(
      outPath('spot.mtl'),
      'newmtl spot\nKd 1 1 1\nKs 0 0 0\nNs 0.5\nmap_Kd spot_texture.png\n',
    );
  });

  const glb = await step('obj2gltf', () =>
    tools.obj2gltf(outPath('spot.obj'), { binary: true, metallicRoughness: true, secure: true }),
  );
  fs.writeFileSync(outPath('spot.glb'), glb);

  const { NodeIO } = tools.core;
  const { ALL_EXTENSIONS, KHRTextureTransform } = tools.extensions;
  const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
  const [mrPng, normalMap] = await step('maps', () => [metallicRoughnessPng(), normalPng()]);
  const fresh = () => io.readBinary(new Uint8Array(glb));
  const image = (doc, name, bytes) =>
    doc.createTexture(name).setImage(new Uint8Array(bytes)).setMimeType('image/png').setURI(`${name}.png`);
  const onlyMaterial = (doc) => {
    const mats = doc.getRoot().listMaterials();
    if (mats.length !== 1) throw new Error(`obj2gltf made ${mats.length} materials, expected 1`);
    return mats[0];
  };
  const addMr = (doc, name) =>
    onlyMaterial(doc)
      .setMetallicRoughnessTexture(image(doc, name, mrPng))
      .setMetallicFactor(1)
      .setRoughnessFactor(1);
  const addNormal = (doc, name) =>
    onlyMaterial(doc).setNormalTexture(image(doc, name, normalMap)).setNormalScale(1);

  await step('gltf-transform spot_mr', async () => {
    const doc = await fresh();
    addMr(doc, 'spot_mr_metallic_roughness');
    await io.write(outPath('spot_mr.glb'), doc);
  });
  await step('gltf-transform spot_normal', async () => {
    const doc = await fresh();
    addNormal(doc, 'spot_normal_normal');
    await io.write(outPath('spot_normal.glb'), doc);
  });
  await step('gltf-transform spot_transform', async () => {
    const doc = await fresh();
    const ext = doc.createExtension(KHRTextureTransform);
    const transform = ext.createTransform().setOffset([0.25, 0]).setRotation(0).setScale([2, 2]);
    const info = onlyMaterial(doc).getBaseColorTextureInfo();
    if (!info) throw new Error('obj2gltf made no base-colour texture');
    info.setExtension('KHR_texture_transform', transform);
    await io.write(outPath('spot_transform.glb'), doc);
  });
  await step('gltf-transform spot_external', async () => {
    const doc = await fresh();
    onlyMaterial(doc).getBaseColorTexture().setURI('spot_external_base_color.png');
    addMr(doc, 'spot_external_metallic_roughness');
    addNormal(doc, 'spot_external_normal');
    doc.getRoot().listBuffers().forEach((b) => b.setURI('spot_external.bin'));
    await io.write(outPath('spot_external.gltf'), doc);
  });
  await step('gltf-transform spot_two', async () => {
    const doc = await fresh();
    const root = doc.getRoot();
    const nodes = root.listNodes().filter((n) => n.getMesh());
    if (nodes.length !== 1) throw new Error(`obj2gltf made ${nodes.length} mesh nodes, expected 1`);
    const [node] = nodes;
    const mesh = node.getMesh();
    const plastic = onlyMaterial(doc).setName('spot_plastic').setMetallicFactor(0).setRoughnessFactor(0.5);
    const metal = plastic.clone().setName('spot_metal').setMetallicFactor(1).setRoughnessFactor(0.3);
    node.setName('spot_plastic');
    mesh.setName('spot_plastic');
    const mesh2 = doc.createMesh('spot_metal');
    for (const prim of mesh.listPrimitives()) mesh2.addPrimitive(prim.clone().setMaterial(metal));
    const pos = mesh.listPrimitives()[0].getAttribute('POSITION');
    const width = pos.getMax([])[0] - pos.getMin([])[0];
    const node2 = doc.createNode('spot_metal').setMesh(mesh2).setTranslation([1.5 * width, 0, 0]);
    root.listScenes().forEach((s) => s.addChild(node2));
    await io.write(outPath('spot_two.glb'), doc);
  });

  const assets = [
    'spot.glb',
    'spot_mr.glb',
    'spot_normal.glb',
    'spot_transform.glb',
    'spot_external.gltf',
    'spot_two.glb',
  ];
  const lines = [];
  const errors = [];
  await step('gltf-validator', async () => {
    for (const a of assets) {
      const report = await validate(tools.validator, outPath(a));
      lines.push(verdictLine(a, report));
      errors.push(...errorMessages(outPath(a), report));
    }
  });
  fs.writeFileSync(outPath('validation.tsv'), `${lines.join('\n')}\n`);
  fs.writeFileSync(outPath('timings.tsv'), `${timings.join('\n')}\n`);
  if (errors.length > 0) {
    errors.forEach((m) => console.error(m));
    console.error(`make_assets: the validator found ${errors.length} errors`);
    process.exit(1);
  }
}

const { cmd, opts } = parseArgs(process.argv.slice(2));
const tools = loadTools(opts.npm);
try {
  if (cmd === 'build') await build(tools, opts);
  else if (cmd === 'validate') await validateFiles(tools, opts.files);
  else usage(`unknown command '${cmd ?? ''}'`);
} catch (e) {
  console.error(`make_assets: ${e.stack ?? e}`);
  process.exit(1);
}
