"""Cars described in one place: :class:`~rkmpc.config.car.CarConfig`, its presets and its files."""
