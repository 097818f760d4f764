"""Rooms and episode starts: furniture and its distance field, rooms, the way round, spawning, scenarios."""
