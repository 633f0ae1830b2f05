// The whole train firmware in the MicroPython WebAssembly port (32-bit, like the ESP8266): boot, connect, report and
// obey commands; prints the heap in use after each boot half and the peaks over the loop, as JSON on the last line.
// Usage: node heap32.mjs MICROPYTHON_MJS TREE_DIR CMD_DIR PASSES IPS_FRAME_HEX
import fs from "fs";
import path from "path";
import { pathToFileURL } from "url";

const [mjs, tree, cmdDir, passesArg, ipsHex] = process.argv.slice(2);
const { loadMicroPython } = await import(pathToFileURL(mjs).href);
const passes = parseInt(passesArg, 10);
const out = [];
const mp = await loadMicroPython({ stdout: (line) => out.push(line) });

function copy(src, dst) {
  for (const name of fs.readdirSync(src)) {
    const s = path.join(src, name), d = dst + "/" + name;
    if (fs.statSync(s).isDirectory()) {
      try { mp.FS.mkdir(d); } catch (e) { /* exists */ }
      copy(s, d);
    } else {
      mp.FS.writeFile(d, fs.readFileSync(s));
    }
  }
}
mp.FS.mkdir("/fw");
copy(tree, "/fw");
mp.FS.mkdir("/cmds");
copy(cmdDir, "/cmds");

const py = (code) => mp.runPython(code);
const heap = () => { py("import gc\ngc.collect()\n_h = gc.mem_alloc()"); return mp.globals.get("_h"); };
py("import sys\nsys.path[:] = ['/fw']\nimport gc\ngc.collect()");
const base = heap();
// the harness, and what a board has in ROM or C: umqtt.simple (frozen), binascii (a Python module in this port)
py("import heap_probe, usocket, umqtt.simple, binascii");
const probe = heap();
// this port never collects inside a call (only between them), so the heap in use at the end of a call is the most
// the call needed, all its garbage included: a strict upper bound of what a board, which does collect, needs
const peakOf = (code) => { py(`_p = ${code} or gc.mem_alloc()`); return mp.globals.get("_p"); };
const bootPeak = peakOf(`heap_probe.boot(bytes.fromhex("${ipsHex}"))`);
const afterBoot = heap();
const assemblePeak = peakOf("heap_probe.assemble()");
const afterAssemble = heap();
let peak = 0, live = 0;
for (let i = 0; i < passes; i++) {
  const ms = 3000 + 10 * i;
  if (i % 12 === 0) py(`heap_probe.feed_ips(bytes.fromhex("${ipsHex}"))`);   // about 8 Hz of IPS fixes
  py(`_u = heap_probe.one_pass(${ms})`);
  peak = Math.max(peak, mp.globals.get("_u"));
  live = Math.max(live, heap());
  py("_h = heap_probe.halved()");
  if (mp.globals.get("_h")) {   // the loop collects after a connection attempt, then the unit steps
    py("_u = heap_probe.second_half()");
    peak = Math.max(peak, mp.globals.get("_u"));
    live = Math.max(live, heap());
  }
}
py("import usocket\n_s = heap_probe.state() + ' %d %d' % (usocket.REPORTS[0], usocket.COMMANDS[0])");
const [mode, seq, cseq, rejected, reports, commands] = mp.globals.get("_s").split(" ");
const shim = probe - base;
console.log(out.join("\n"));
console.log(JSON.stringify({
  interpreter_b: base, harness_b: shim, after_boot_b: afterBoot - base - shim,
  after_assemble_b: afterAssemble - base - shim, boot_peak_b: bootPeak - base - shim,
  assemble_peak_b: assemblePeak - base - shim, loop_live_peak_b: live - base - shim,
  loop_peak_before_collection_b: peak - base - shim, passes, mode, reports_sent: +seq, reports_seen: +reports,
  commands_sent: +commands, last_command_taken: +cseq, commands_rejected: +rejected,
}));
