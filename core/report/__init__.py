"""The run report: its images and numbers (``make``), the picture (``figure``) and one colour
per level (``level_colors``)."""
