// Tokens on a diagram, as every view of the studio draws them: the element outlined
// (`trace-live`) and a badge with the count, in overlays of `type` (so each view clears its own).

/** Draws `tokens` (element id → count) on `diagram` (a bpmn-js modeler or viewer). */
export function showTokens(diagram, tokens, type) {
  const canvas = diagram.get('canvas');
  const overlays = diagram.get('overlays');
  const registry = diagram.get('elementRegistry');
  for (const [id, n] of Object.entries(tokens)) {
    const el = registry.get(id);
    if (!el) continue;
    canvas.addMarker(el, 'trace-live');
    const badge = document.createElement('div');
    badge.className = 'trace-token';
    badge.textContent = String(n);
    overlays.add(el, type, { position: { bottom: 0, left: -9 }, html: badge });
  }
}
