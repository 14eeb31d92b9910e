//! The representative aircraft of the virtual flight test: reference values
//! ([`turboprop`]), the qualified table model ([`qualified`]), the library of
//! switchable post-stall effects ([`effects`]) and the truth model ([`truth`]).

pub mod effects;
pub mod qualified;
pub mod records;
pub mod truth;
pub mod turboprop;
