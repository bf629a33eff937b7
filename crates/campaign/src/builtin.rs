//! The reference planner as a [`Planner`](fogline_types::planner::Planner): in-process, no
//! encoding, no network. The implementation lives with the planner (`fogline-planner`); this
//! name is what campaign configurations call `builtin`.

/// The built-in reference planner behind the `Planner` interface.
pub type BuiltinPlanner = fogline_planner::ReferencePlanner;
