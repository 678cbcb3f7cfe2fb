//! Shared helpers of the integration tests: a small deterministic
//! pseudo-random generator, random scenes, and an independent evaluation of
//! the quantities the damping models must keep.
//!
//! Every test binary uses a different subset, hence the `dead_code` allow.
#![allow(dead_code)]

use nalgebra::Matrix3;
use pd_damping::{DampingContext, Point};

/// Unit round-off of f64: every basic operation is exact up to a relative
/// error of at most `U`.
pub const U: f64 = f64::EPSILON / 2.0;

/// Random cases per property.
pub const CASES: u64 = 2000;

/// SplitMix64 (Steele, Lea, Flood 2014): tiny, full-period, good enough to
/// spread test cases; a fixed seed per test keeps failures reproducible.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[low, high)`.
    pub fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.uniform()
    }

    /// Log-uniform in `[low, high)`, both positive.
    pub fn log_range(&mut self, low: f64, high: f64) -> f64 {
        (self.range(low.ln(), high.ln())).exp()
    }

    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Each component uniform in `[-scale, scale)`.
    pub fn vector(&mut self, scale: f64) -> Point {
        Point::new(
            self.range(-scale, scale),
            self.range(-scale, scale),
            self.range(-scale, scale),
        )
    }

    /// A random direction.
    pub fn unit_vector(&mut self) -> Point {
        loop {
            let candidate = self.vector(1.0);
            let norm = candidate.norm();
            if norm > 0.1 && norm <= 1.0 {
                return candidate / norm;
            }
        }
    }

    /// A damping factor in `[0, 1]`, hitting both ends now and then.
    pub fn factor(&mut self) -> f64 {
        match self.below(8) {
            0 => 0.0,
            1 => 1.0,
            _ => self.uniform(),
        }
    }
}

/// The shape of a random body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// 3 to 12 vertices scattered in a box: a regular inertia tensor.
    Cloud,
    /// 3 to 12 vertices on a line along a random direction: the inertia is
    /// singular about the line.
    Chain,
    /// Two vertices (a chain of two).
    Pair,
    /// One vertex: zero inertia.
    Single,
}

pub const SHAPES: [Shape; 4] = [Shape::Cloud, Shape::Chain, Shape::Pair, Shape::Single];

/// Vertex data of a few bodies plus fixed and loose vertices, with the
/// indices shuffled so that no body occupies a contiguous range.
#[derive(Debug, Clone)]
pub struct Scene {
    pub masses: Vec<f64>,
    pub positions: Vec<Point>,
    pub velocities: Vec<Point>,
    pub components: Vec<Vec<usize>>,
    pub fixed: Vec<bool>,
}

impl Scene {
    /// A context over this scene with time step `h` (s).
    pub fn context(&self, h: f64) -> DampingContext<'_> {
        DampingContext {
            h,
            masses: &self.masses,
            bodies: &[],
            components: &self.components,
            fixed: &self.fixed,
        }
    }

    /// Vertices in no component (fixed ones included).
    pub fn outside_components(&self) -> Vec<usize> {
        let mut inside = vec![false; self.masses.len()];
        for component in &self.components {
            for &vertex in component {
                inside[vertex] = true;
            }
        }
        (0..self.masses.len()).filter(|&i| !inside[i]).collect()
    }
}

/// Positions and velocities of one body of `shape`, at a random length scale
/// far from the origin (so angular momentum about the origin and about the
/// centre differ a lot), with random masses spanning six decades and
/// velocities mixing a large translation, a rotation and noise.
fn random_body(rng: &mut Rng, shape: Shape) -> Vec<(f64, Point, Point)> {
    let count = match shape {
        Shape::Cloud | Shape::Chain => 3 + rng.below(10),
        Shape::Pair => 2,
        Shape::Single => 1,
    };
    let length = rng.log_range(1e-3, 1e3);
    let speed = rng.log_range(1e-3, 1e3);
    let origin = rng.vector(100.0 * length);
    let direction = rng.unit_vector();
    let translation = rng.vector(10.0 * speed);
    let spin = rng.vector(speed / length);
    (0..count)
        .map(|_| {
            let offset = match shape {
                Shape::Cloud => rng.vector(length),
                Shape::Chain | Shape::Pair | Shape::Single => {
                    direction * rng.range(-length, length)
                }
            };
            let position = origin + offset;
            let velocity = translation + spin.cross(&offset) + rng.vector(speed);
            (rng.log_range(1e-3, 1e3), position, velocity)
        })
        .collect()
}

/// A scene of 1 to 4 bodies of random shapes, 0 to 2 fixed vertices (zero
/// velocity) and 0 to 2 loose vertices (in no component, moving).
pub fn random_scene(rng: &mut Rng) -> Scene {
    let shapes: Vec<Shape> = (0..1 + rng.below(4))
        .map(|_| SHAPES[rng.below(SHAPES.len())])
        .collect();
    random_scene_of(rng, &shapes)
}

/// A scene of bodies of the given shapes plus fixed and loose vertices.
pub fn random_scene_of(rng: &mut Rng, shapes: &[Shape]) -> Scene {
    // (mass, position, velocity, component or None, fixed)
    let mut vertices = Vec::new();
    for (body, &shape) in shapes.iter().enumerate() {
        for (mass, position, velocity) in random_body(rng, shape) {
            vertices.push((mass, position, velocity, Some(body), false));
        }
    }
    for _ in 0..rng.below(3) {
        vertices.push((1.0, rng.vector(10.0), Point::zeros(), None, true));
    }
    for _ in 0..rng.below(3) {
        vertices.push((1.0, rng.vector(10.0), rng.vector(10.0), None, false));
    }
    // Fisher-Yates.
    for i in (1..vertices.len()).rev() {
        vertices.swap(i, rng.below(i + 1));
    }
    let mut scene = Scene {
        masses: Vec::new(),
        positions: Vec::new(),
        velocities: Vec::new(),
        components: vec![Vec::new(); shapes.len()],
        fixed: Vec::new(),
    };
    for (index, (mass, position, velocity, body, fixed)) in vertices.into_iter().enumerate() {
        scene.masses.push(mass);
        scene.positions.push(position);
        scene.velocities.push(velocity);
        scene.fixed.push(fixed);
        if let Some(body) = body {
            scene.components[body].push(index);
        }
    }
    scene
}

/// The rigid fit of one component, computed here independently of
/// `pd_damping::rigid` (the pseudo-inverse by SVD instead of a symmetric
/// eigendecomposition), with the magnitudes the tolerances need.
#[derive(Debug, Clone, Copy)]
pub struct Reference {
    pub centre: Point,
    pub linear_velocity: Point,
    pub angular_momentum: Point,
    pub angular_velocity: Point,
    /// Largest over smallest retained eigenvalue of the inertia tensor (1 when
    /// it is zero).
    pub condition: f64,
    /// Smallest retained eigenvalue (kg m^2), 0 when none is.
    pub smallest_inertia: f64,
    /// Largest eigenvalue (kg m^2).
    pub largest_inertia: f64,
}

impl Reference {
    pub fn of(component: &[usize], scene: &Scene) -> Self {
        let masses = &scene.masses;
        let positions = &scene.positions;
        let velocities = &scene.velocities;
        let mass: f64 = component.iter().map(|&i| masses[i]).sum();
        let centre = component
            .iter()
            .map(|&i| masses[i] * positions[i])
            .sum::<Point>()
            / mass;
        let linear_velocity = component
            .iter()
            .map(|&i| masses[i] * velocities[i])
            .sum::<Point>()
            / mass;
        let mut angular_momentum = Point::zeros();
        let mut inertia = Matrix3::zeros();
        for &i in component {
            let r = positions[i] - centre;
            // Relative to v_cm, or a large common velocity would drown J in
            // round-off (a lone vertex would get a huge, arbitrary omega).
            angular_momentum += masses[i] * r.cross(&(velocities[i] - linear_velocity));
            inertia += masses[i] * (Matrix3::identity() * r.dot(&r) - r * r.transpose());
        }
        let singular_values = inertia.singular_values();
        let largest = singular_values.max();
        let cutoff = 1e-12 * largest;
        let retained = singular_values.iter().copied().filter(|&s| s > cutoff);
        let smallest_inertia = retained.fold(f64::INFINITY, f64::min);
        let (angular_velocity, condition, smallest_inertia) = if largest > 0.0 {
            let pseudo_inverse = inertia.pseudo_inverse(cutoff).expect("cutoff >= 0");
            (
                pseudo_inverse * angular_momentum,
                largest / smallest_inertia,
                smallest_inertia,
            )
        } else {
            (Point::zeros(), 1.0, 0.0)
        };
        Self {
            centre,
            linear_velocity,
            angular_momentum,
            angular_velocity,
            condition,
            smallest_inertia,
            largest_inertia: largest,
        }
    }

    /// The rigid velocity (m/s) at `position`.
    pub fn rigid_velocity(&self, position: &Point) -> Point {
        self.linear_velocity + self.angular_velocity.cross(&(position - self.centre))
    }
}

/// Linear momentum (kg m/s) of the listed vertices.
pub fn linear_momentum(component: &[usize], masses: &[f64], velocities: &[Point]) -> Point {
    component.iter().map(|&i| masses[i] * velocities[i]).sum()
}

/// Angular momentum (kg m^2/s) of the listed vertices about `point`.
pub fn angular_momentum(
    component: &[usize],
    masses: &[f64],
    positions: &[Point],
    velocities: &[Point],
    point: &Point,
) -> Point {
    component
        .iter()
        .map(|&i| (positions[i] - point).cross(&(masses[i] * velocities[i])))
        .sum()
}

/// Kinetic energy (J) of the listed vertices.
pub fn kinetic_energy(component: &[usize], masses: &[f64], velocities: &[Point]) -> f64 {
    component
        .iter()
        .map(|&i| 0.5 * masses[i] * velocities[i].norm_squared())
        .sum()
}
