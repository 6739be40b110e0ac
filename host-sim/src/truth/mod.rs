//! The truth the machine is measured against: continuous `f64` geometry, independent of the
//! cells' integer arithmetic (it never imports the machine).
//!
//! * [`visibility`] — exact ray–triangle visibility over a BVH.
//! * [`closed_form`] — exact form factors without visibility: the contour integral (Eq. 2.2)
//!   and Howell's catalogue (Renaud 1993, ch. 2).
//! * [`formfactor`] — form factors between radiosity patches, sampled with exact visibility
//!   (Renaud 1993, ch. 2 and §3.1).
//! * [`projective`] — the projective form-factor methods of Renaud 1993 ch. 2 (hemicube,
//!   single planes, hemispheres, disk) and §2.5's tables.
//! * [`raytraced`] — form factors from a point toward a source by rays (Wallace) and by the
//!   thesis's subdivided beam (Renaud 1993, ch. 3).
//! * [`radiosity`] — progressive-refinement radiosity, the reference solution, and a direct
//!   solve of the same system (Renaud 1993, §1.3).
//! * [`refrender`] — the f64 reference image (same camera, lights and shading formula).
//! * [`compare`] — the machine's image against the reference: shadow and coverage
//!   disagreement, PSNR, difference image.

pub mod closed_form;
pub mod compare;
pub mod formfactor;
pub mod projective;
pub mod radiosity;
pub mod raytraced;
pub mod refrender;
pub mod visibility;
