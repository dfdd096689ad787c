"""The microscopic model: every cell wall resolved (docs/model.md section 7) and the biological
cells' outlines written next to it."""
