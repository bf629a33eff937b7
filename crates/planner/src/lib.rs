//! The reference planner: sees only camera frames and the ego history.
