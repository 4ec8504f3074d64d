use sim::arm::SimArm;
use sim::physics::Cell;
use sim::world::PhysicsSpec;
use std::path::Path;
fn main() {
    let base = mesh::pose::from_position_rpy_deg([0.0, 0.3, 0.0], [0.0, 0.0, -90.0]);
    let robot_arm = robot::Arm::from_urdf_file(Path::new("urdf/umi_rtx.urdf")).unwrap();
    let q = [0.2974996243598885, -1.0345955960237685, 2.031138873841097, -0.6926938581890218, -2.525955605810238e-6, 1.5848333238336192];
    let mut cell = Cell::new(&PhysicsSpec::default(), &[]);
    let arm = SimArm::insert(&mut cell, Path::new("urdf/umi_rtx.urdf"), &base, &q, 0.04).unwrap();
    cell.world.step();
    let fk = robot_arm.link_poses(&q, 0.04);
    for (i, b) in arm.bodies.iter().enumerate() {
        let p = cell.world.bodies[*b].position();
        let name = &robot_arm.links[i].name;
        let f = base * fk[i];
        println!("{name}: sim {:?} fk {:?}", p.translation, f.translation.vector.as_slice());
        for c in cell.world.bodies[*b].colliders() {
            let co = &cell.world.colliders[*c];
            let s = &robot_arm.links[i].shapes; if !s.is_empty() { let e = base * fk[i] * s[0].link_from_shape; println!("   collider at {:?} expect {:?}", co.position().translation, e.translation.vector.as_slice()); }
        }
    }
}
