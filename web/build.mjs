// Bundles the viewer into one folder the server serves as it is: index.html, viewer.js (three.js
// and the viewer, one ES module) and draco/ (three.js's Draco decoder). Nothing is fetched from
// the internet when the page runs. Usage: node build.mjs OUT_DIR
import { build } from 'esbuild';
import { copyFileSync, mkdirSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const out = process.argv[2] || join(here, 'dist');
mkdirSync(join(out, 'draco'), { recursive: true });
await build({
  entryPoints: [join(here, 'src', 'viewer.js')],
  bundle: true,
  format: 'esm',
  minify: true,
  sourcemap: false,
  target: 'es2020',
  outfile: join(out, 'viewer.js'),
  logLevel: 'warning',
});
copyFileSync(join(here, 'index.html'), join(out, 'index.html'));
const draco = join(here, 'node_modules', 'three', 'examples', 'jsm', 'libs', 'draco');
for (const file of ['draco_decoder.wasm', 'draco_wasm_wrapper.js', 'draco_decoder.js']) copyFileSync(join(draco, file), join(out, 'draco', file));
console.log(`viewer bundled into ${out}`);
