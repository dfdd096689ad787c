"""The microscopic model: every cell wall resolved (MODEL.md section 7) and the biological cells'
outlines written next to it."""
