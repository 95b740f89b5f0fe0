"""The world: prepared static scenes, moving bodies and Embree instances, cast as one; a cast's returns."""
