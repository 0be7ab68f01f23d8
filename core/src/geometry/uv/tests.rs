use super::*;
use crate::geometry::aggregate::Geometry;
use crate::geometry::ray::Ray;
use crate::geometry::shapes::{Sphere, cube, disk, rectangle};
use glam::{Affine3A, Mat4, Quat};

/// The texture coordinates where `ray` meets the geometry.
fn uv_along(geometry: &Geometry, origin: Vec3, direction: Vec3) -> Vec2 {
    let ray = Ray {
        origin,
        direction,
        t_max: f32::INFINITY,
    };
    let hit = geometry.intersect(&ray).expect("the ray meets the shape");
    geometry.uv(&hit)
}

fn close(a: Vec2, b: Vec2) -> bool {
    (a - b).abs().max_element() < 2e-5
}

/// Mitsuba 3.9.1's texture coordinates (`scene.ray_intersect(ray).uv`, scalar_rgb) at the
/// same rays, for its `cube`, `rectangle`, `disk` and `sphere` (unrotated and turned 90°
/// about z): each face of the cube, the polar disk, the spherical angles in the shape's
/// frame.
#[test]
fn built_in_shapes_have_mitsubas_texture_coordinates() {
    let cube_hits = [
        ((0.0, -3.0, 0.2), (0.0, 1.0, 0.0), (0.6, 0.5)),
        ((0.3, 3.0, 0.2), (0.0, -1.0, 0.0), (0.35, 0.4)),
        ((3.0, 0.3, 0.2), (-1.0, 0.0, 0.0), (0.65, 0.4)),
        ((0.3, 0.5, 3.0), (0.0, 0.0, -1.0), (0.75, 0.65)),
        ((-3.0, 0.3, 0.2), (1.0, 0.0, 0.0), (0.65, 0.6)),
        ((0.3, 0.5, -3.0), (0.0, 0.0, 1.0), (0.25, 0.65)),
    ];
    let geometry = Geometry::new(vec![ShapeGeometry::Mesh(cube())]);
    for (origin, direction, uv) in cube_hits {
        let got = uv_along(&geometry, origin.into(), direction.into());
        assert!(
            close(got, uv.into()),
            "cube from {origin:?}: {got} against {uv:?}"
        );
    }
    let down = Vec3::new(0.0, 0.0, -1.0);
    let above = Vec3::new(0.3, -0.6, 3.0);
    let geometry = Geometry::new(vec![ShapeGeometry::Mesh(rectangle())]);
    assert!(close(
        uv_along(&geometry, above, down),
        Vec2::new(0.65, 0.2)
    ));
    // A disk of 1024 segments, so that its fan covers the point; the mapping is polar.
    let geometry = Geometry::new(vec![ShapeGeometry::Mesh(disk(1024))]).with_uv_mappings(vec![
        UvMapping::Polar {
            to_object: Affine3A::IDENTITY,
        },
    ]);
    let got = uv_along(&geometry, above, down);
    assert!(close(got, Vec2::new(0.67082, 0.823792)), "disk: {got}");
    let unit = ShapeGeometry::Sphere(Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
    });
    let geometry = Geometry::new(vec![unit.clone()]);
    for (origin, uv) in [
        ((0.3, -0.6, 3.0), (0.823792, 0.0700243)),
        ((0.3, 0.6, -3.0), (0.176208, 0.929976)),
        ((3.0, 0.1, 0.2), (0.0053032, 0.478822)),
    ] {
        let origin = Vec3::from(origin);
        let got = uv_along(&geometry, origin, -origin);
        assert!(
            close(got, uv.into()),
            "sphere from {origin}: {got} against {uv:?}"
        );
    }
    let turned = Mat4::from_quat(Quat::from_rotation_z(90f32.to_radians()));
    let geometry = Geometry::new(vec![unit]).with_uv_mappings(vec![UvMapping::Sphere {
        to_object: Mat3::from_mat4(turned).inverse(),
    }]);
    let got = uv_along(&geometry, Vec3::new(3.0, 0.1, 0.2), -Vec3::X);
    assert!(
        close(got, Vec2::new(0.766272, 0.435906)),
        "turned sphere: {got}"
    );
}

/// A mesh's vertex UVs are interpolated at the hit; without them, the hit's barycentrics
/// (b1, b2) are its coordinates, as in Mitsuba. A mapping that gives no finite value (a
/// degenerate transform) gives (0, 0).
#[test]
fn meshes_interpolate_their_vertex_uvs() {
    let triangle = |uvs| Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ],
        normals: None,
        indices: vec![[0, 1, 2]],
        uvs,
    };
    let point = Vec3::new(1.0, 0.5, 5.0);
    let down = -Vec3::Z;
    let plain = Geometry::new(vec![ShapeGeometry::Mesh(triangle(None))]);
    assert!(close(uv_along(&plain, point, down), Vec2::new(0.25, 0.25)));
    let uvs = vec![
        Vec2::new(0.5, 0.5),
        Vec2::new(1.5, 0.5),
        Vec2::new(0.5, -1.5),
    ];
    let textured = Geometry::new(vec![ShapeGeometry::Mesh(triangle(Some(uvs)))]);
    assert!(close(
        uv_along(&textured, point, down),
        Vec2::new(0.75, 0.0)
    ));
    let degenerate = plain.with_uv_mappings(vec![UvMapping::Polar {
        to_object: Affine3A::from_mat4(Mat4::ZERO).inverse(),
    }]);
    assert_eq!(uv_along(&degenerate, point, down), Vec2::ZERO);
}
