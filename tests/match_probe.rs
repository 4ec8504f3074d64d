use std::path::Path;
use vision::matcher::{MatchParams, MatcherModel, Seg, locate_all, support_at};
#[test]
fn probe() {
    let scn = sim::Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/widgets.toml")).unwrap();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let models: Vec<MatcherModel> = scn.library.models.values().filter(|m| m.name != "flag").map(MatcherModel::from_model).collect();
    for seed in 1..=12u64 {
        let scene = sim::Scene::settle(&scn, seed);
        let rs = sim::render::RenderScene::new(scene.world_meshes(&scn.library), &sim::render::Light::from(&scn.world.light));
        let (l, r) = sim::render::render_stereo(&rs, &calib, 1.5, seed);
        let li = vision::GreyImage::new(l.width, l.height, l.image).unwrap();
        let ri = vision::GreyImage::new(r.width, r.height, r.image).unwrap();
        let fe = vision::slices::run_sliced(&li, &ri, &calib, &vision::CannyParams::default(), 8);
        let lines: Vec<Seg> = fe.lines3d.iter().map(|l| Seg::new(l.start(), l.end())).collect();
        let ev = vision::verify::ImageEvidence { cam: &calib.left, edges: &fe.left };
        let p = MatchParams::default();
        let located = locate_all(&models, &lines, &p, Some(&ev));
        for o in &scene.objects {
            let m = models.iter().find(|m| m.name == o.model).unwrap();
            let truth = calib.left.cam_from_world() * o.world_from_model;
            let found = located.iter().any(|x| x.model == o.model && (x.cam_from_model.translation.vector - truth.translation.vector).norm() < 0.01);
            if !found {
                let (frac, nl) = support_at(m, &truth, &lines, &p);
                let img = vision::verify::image_support(m, &truth, &ev);
                let alone = vision::matcher::locate(m, &lines, &p, Some(&ev));
                eprintln!("seed {seed} missed {:10}: at truth support {:.2} over {} lines, image {:.2}; alone found {} reports: {:?}", o.model, frac, nl, img, alone.len(), alone.iter().map(|a| ((a.cam_from_model.translation.vector - truth.translation.vector).norm() * 1e3).round()).collect::<Vec<_>>());
            }
        }
    }
}
