"""``ultraglide serve``'s room: the WebSocket server in front of the engine (:mod:`.server`), its message protocol
(:mod:`.protocol`), views and sprites composed into what the engine renders (:mod:`.scene`), and the page with its
JavaScript module (``page/``, package data)."""
