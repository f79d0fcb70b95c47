"""From a Recording to images: matched filter, snapshots, steering, DOA, broadband energyscapes,
images, peaks, metrics."""
