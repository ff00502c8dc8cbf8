// The page's bookkeeping of live-map changes (GET /api/events `submaps` events, docs/serve-design.md
// "Live mode"), apart from drawing (no three.js) so that node tests it without a browser
// (viewer/test/live_changes.mjs). A drawn chunk belongs to its submap (`chunk.submap`); once that
// submap is merged into another, it is held by the target (`chunk.heldBy`) until the target's
// chunks, which now contain the merged voxels, are fetched and replace it: drawing both would
// draw the merged voxels twice, and dropping it before the target's chunks are here would blank
// the place meanwhile.

// A merged submap's chunks, and those it held from earlier merges, are held by the submap it went
// into from now on.
export function applyMerges(chunks, merged) {
  for (const { id, into } of merged ?? [])
    for (const chunk of chunks)
      if (chunk.submap === id || chunk.heldBy === id) chunk.heldBy = into;
}

// Whether chunks fetched anew for submap `id` replace this drawn chunk.
export function replacedBy(chunk, id) {
  return chunk.submap === id || chunk.heldBy === id;
}

// Keeps `outOfMemory` (a Set of ids) in step with one event: unloaded submaps are still in the map
// file, only out of memory; the live server answers from memory only, so the page keeps what it
// drew of them (their chunks are left as they are) until they come back as `added`.
export function trackMemory(outOfMemory, change) {
  for (const id of change.unloaded ?? []) outOfMemory.add(id);
  for (const s of change.added ?? []) outOfMemory.delete(s.id);
}

// The submaps whose chunks to fetch anew after one event, each once, in the event's order: new and
// grown ones, and merge targets (they hold the merged voxels now), but neither a submap merged
// away nor one out of memory (nothing to fetch: a target out of memory keeps holding the merged
// chunks and replaces them when it comes back).
export function submapsToFetch(change, outOfMemory) {
  const merged = change.merged ?? [];
  const gone = new Set(merged.map((m) => m.id));
  const ids = [...(change.added ?? []).map((s) => s.id), ...(change.grew ?? []), ...merged.map((m) => m.into)];
  return [...new Set(ids)].filter((id) => !gone.has(id) && !outOfMemory.has(id));
}

// A `moved` event's new anchors (`toT`: the event's rows as the chunks hold them), for every drawn
// chunk of those submaps, in memory or not (a loop correction moves submaps that left memory too,
// and the page keeps what it drew of them). Returns the chunks placed anew.
export function applyMoves(chunks, moved, toT) {
  const T = new Map((moved ?? []).map((s) => [s.id, toT(s.T_world_submap)]));
  const placed = chunks.filter((chunk) => T.has(chunk.submap));
  for (const chunk of placed) chunk.T = T.get(chunk.submap);
  return placed;
}

// A `resync` (the stream fell behind: everything is fetched anew): `outOfMemory` becomes the
// event's list of submaps out of memory, and the drawn chunks to drop are returned: all but those
// of submaps out of memory (their own, or held for a merge), which the fetch cannot bring back
// (the live server answers from memory only).
export function chunksDroppedOnResync(chunks, change, outOfMemory) {
  outOfMemory.clear();
  for (const id of change.unloaded ?? []) outOfMemory.add(id);
  return chunks.filter((chunk) => !outOfMemory.has(chunk.heldBy ?? chunk.submap));
}
