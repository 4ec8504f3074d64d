//! The model matcher (Pollard, Porrill, Mayhew & Frisby, as TINA uses it): the second of
//! MARVIN's two phases, which finds known objects among the 3D lines the front end recovers.
//!
//! - The model is its wireframe: directed 3D segments, with the grasp positions of the library.
//! - Featural parallelism: the model is split into six characteristic views (the lines on faces
//!   turned towards a viewer looking along one of the model's axes); a subordinate matcher per
//!   view searches the scene, all in parallel, and the virtual matcher ([`locate`]) keeps the
//!   best of their hypotheses and looks again for further instances. (The views overlap so
//!   much that, their shared pairs tabled once, most of the work falls to the first.)
//! - Pairwise relations (the angle between two lines, their perpendicular separation and where
//!   along each the closest approach falls, as in Grimson & Lozano-Perez's tables) are tabled
//!   per view for the pairs that matter: each focus line (the view's longest in each direction
//!   by turns, in the manner of Bolles) with its feature group (the view's lines not parallel
//!   to it); pairs that the model's symmetry makes equivalent are tabled once.
//! - Hypotheses: a scene pair congruent with a focus pair, within tolerances that let fragments
//!   and partly seen lines qualify, gives a pose by least squares ([`pose_fit`]).
//! - Each hypothesis is ranked by the support its pose finds: the length of scene lines lying
//!   along the transformed model lines. The best dozen are refined on their supporting sets and
//!   verified in order of that support times the image evidence ([`verify`]): enough of
//!   the model seen, along enough lines, and along the left image's edgels; the pose of the one
//!   that passes is refined on the image too ([`image_fit`]). Further instances come
//!   from the same hypotheses rescored without the lines already explained.
//!
//! Scene lines come from stereo with no particular direction, so each is used both ways round.
//!
//! The modules, in the order a search runs through them:
//!
//! - [`model`]: the model as the matcher holds it, segments, parameters, a located object.
//! - [`views`]: characteristic views and the pairwise tables of their focus pairs.
//! - [`pose_fit`]: least-squares pose from 3D line correspondences (quaternion method).
//! - [`support`]: the support a pose finds among the scene lines.
//! - [`hypotheses`]: poses from congruent scene and focus pairs, scored by support.
//! - [`ranking`]: the best hypotheses refined, ranked with the image evidence.
//! - [`verify`]: a located model checked against the edgels of the left image.
//! - [`image_fit`]: pose refinement on the left image's edgels and the 3D lines together, or on
//!   the edgels of both images at once (the calibration flag's stereo fit).
//! - [`search`]: one model's virtual matcher, instance after instance.
//! - [`occlusion`]: located solids (and a model's own bulk) hiding parts of a wireframe.
//! - [`second_look`]: objects with too few 3D lines, from one 3D line and an image line.
//! - [`depths`]: stereo's depths at the left image's matched edgels.
//! - [`turns`]: the half turns that carry a part most nearly onto itself (what it is misread as).
//! - [`superset`]: a part read as a smaller model its shape holds (a bracket for a channel).
//! - [`covering`]: a part read as another model whose shape covers much of its own (a block
//!   for a wedge), read again as that model where the image shows it better.
//! - [`turnover`]: a part read turned over, turned back where the edgels' depths or the image say so.
//! - [`light`]: the scene's light as faces' grey levels show it.
//! - [`shading`]: the grey levels of a reading's faces, read off the edgels beside its edges.
//! - [`contrast`]: which of a reading's edges the light lets the image show.
//! - [`table`]: the table the parts rest on; readings through it are refused.
//! - [`table_look`]: parts lying flat on the table on too few 3D lines for the first look.
//! - [`image_look`]: parts lying flat on the table on no 3D line, from an image corner and both images.
//! - [`ties`]: two readings of different models on the same 3D evidence, told apart where
//!   they differ in the image.
//! - [`see_through`]: depth order, a reading whose solid would stand in front of edges stereo
//!   found behind it.
//! - [`overlap`]: two reports filling the same space; the weaker is not there.
//! - [`merge`]: all models in parallel, reports merged, the second, third and table looks.
//! - [`polish`]: each report's pose pulled onto the edgels of both images at once, and turned
//!   where both images show a turn of it more sharply; [`polish::doubt`]: the reports a turn
//!   of the part fits as well (a run picks them last).
//!
//! The matcher depends on the front end's output types only ([`crate::front_end`]), never the
//! other way round; within it, [`model`] is what the others share and imports none of them.

pub mod contrast;
pub mod covering;
pub mod depths;
pub mod hypotheses;
pub mod image_fit;
pub mod image_look;
pub mod light;
pub mod merge;
pub mod model;
pub mod occlusion;
pub mod overlap;
pub mod polish;
pub mod pose_fit;
pub mod ranking;
pub mod search;
pub mod second_look;
pub mod see_through;
pub mod shading;
pub mod superset;
pub mod support;
pub mod table;
pub mod table_look;
pub mod ties;
pub mod turnover;
pub mod turns;
pub mod verify;
pub mod views;

#[cfg(test)]
pub(crate) mod fixtures;

pub use merge::locate_all;
pub use model::{Located, MatchParams, MatcherModel, Seg, Table};
pub use search::locate;
pub use support::{correspondences_at, support_at};
