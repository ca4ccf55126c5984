"""The Micro-Mesh N-panel."""
