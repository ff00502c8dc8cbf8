// The serve page's live bookkeeping (viewer/src/live_changes.js) without a browser: a merged
// submap's chunks are replaced by its target's next fetch (not drawn beside it), an unloaded
// submap's chunks stay drawn and it is not fetched, and merges of merges follow the chain; a loop
// correction re-places the chunks of a submap out of memory; a resync keeps only those of the
// submaps it lists as out of memory.
// Exits 0 when all hold; run by LiveMapEvents.PageReplacesMergedChunksAndKeepsUnloadedOnes.
//   node viewer/test/live_changes.mjs
import assert from 'node:assert/strict';
import { applyMerges, applyMoves, chunksDroppedOnResync, replacedBy, submapsToFetch, trackMemory } from '../src/live_changes.js';

const chunk = (submap) => ({ submap });
const drawn = [chunk(0), chunk(0), chunk(1), chunk(2), chunk(3)];
const outOfMemory = new Set();
const replacedByFetchOf = (id) => drawn.filter((c) => replacedBy(c, id)).map((c) => c.submap);

// 0 merged into 1 and 2 unloaded, as LiveMapService reports them.
const first = { added: [], moved: [], grew: [], merged: [{ id: 0, into: 1 }], unloaded: [2] };
applyMerges(drawn, first.merged);
trackMemory(outOfMemory, first);
assert.deepEqual(submapsToFetch(first, outOfMemory), [1]);   // the target, not 0, not 2
assert.deepEqual(replacedByFetchOf(1), [0, 0, 1]);            // 1's fetch replaces 0's chunks too
assert.deepEqual(replacedByFetchOf(2), [2]);                  // kept: nothing replaces them now
assert.ok(outOfMemory.has(2));

// 1 merged into 3 later: the chunks 1 held go with it.
const second = { added: [], moved: [], grew: [3], merged: [{ id: 1, into: 3 }], unloaded: [] };
applyMerges(drawn, second.merged);
trackMemory(outOfMemory, second);
assert.deepEqual(submapsToFetch(second, outOfMemory), [3]);  // once, though it also grew
assert.deepEqual(replacedByFetchOf(3), [0, 0, 1, 3]);

// A merge into a submap out of memory: nothing fetched; its chunks wait for it to come back.
const third = { added: [], moved: [], grew: [], merged: [{ id: 3, into: 2 }], unloaded: [] };
applyMerges(drawn, third.merged);
trackMemory(outOfMemory, third);
assert.deepEqual(submapsToFetch(third, outOfMemory), []);
const back = { added: [{ id: 2 }], moved: [], grew: [], merged: [], unloaded: [] };
trackMemory(outOfMemory, back);
assert.deepEqual(submapsToFetch(back, outOfMemory), [2]);
assert.deepEqual(replacedByFetchOf(2), [0, 0, 1, 2, 3]);     // everything it holds now
assert.equal(outOfMemory.size, 0);

// A correction while 4 is out of memory: its kept chunks take the new anchor (rows as the server
// sends them), in memory ones too, and nothing is fetched for 4.
const rows = (x) => [[1, 0, 0, x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
const toT = (r) => r.map((row) => row[3]).slice(0, 3);
const more = [chunk(4), chunk(4), chunk(5)];
const unload4 = { added: [], moved: [], grew: [], merged: [], unloaded: [4] };
trackMemory(outOfMemory, unload4);
const correction = { added: [], moved: [{ id: 4, T_world_submap: rows(2) }, { id: 5, T_world_submap: rows(3) }], grew: [], merged: [], unloaded: [] };
assert.deepEqual(applyMoves(more, correction.moved, toT).map((c) => c.submap), [4, 4, 5]);
assert.deepEqual(more.map((c) => c.T), [[2, 0, 0], [2, 0, 0], [3, 0, 0]]);
trackMemory(outOfMemory, correction);
assert.deepEqual(submapsToFetch(correction, outOfMemory), []);
assert.ok(outOfMemory.has(4));

// A resync listing 4 as out of memory: 4's chunks and those it holds stay, the rest is dropped
// (the full fetch brings what is in memory); 2, back in memory meanwhile, is no longer out of it.
const held = { submap: 6, heldBy: 4 };
const all = [...drawn, ...more, held];
outOfMemory.add(2);
const resync = { changes: 9, resync: true, unloaded: [4], moved: [{ id: 4, T_world_submap: rows(2) }] };
const dropped = chunksDroppedOnResync(all, resync, outOfMemory);
assert.deepEqual(all.filter((c) => !dropped.includes(c)), [more[0], more[1], held]);
assert.deepEqual([...outOfMemory], [4]);
assert.deepEqual(chunksDroppedOnResync(all, { changes: 10, resync: true }, outOfMemory).length, all.length);  // none listed: all anew
console.log('live_changes: ok');
