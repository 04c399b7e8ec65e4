"""Planning: the press, the job file, placement of the plate on the bed, ball-tip contact, strokes and steps."""
