// The serve page's live bookkeeping (viewer/src/live_changes.js) without a browser: a merged
// submap's chunks are replaced by its target's next fetch (not drawn beside it), an unloaded
// submap's chunks stay drawn and it is not fetched, and merges of merges follow the chain.
// Exits 0 when all hold; run by LiveMapEvents.PageReplacesMergedChunksAndKeepsUnloadedOnes.
//   node viewer/test/live_changes.mjs
import assert from 'node:assert/strict';
import { applyMerges, replacedBy, submapsToFetch, trackMemory } from '../src/live_changes.js';

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
console.log('live_changes: ok');
