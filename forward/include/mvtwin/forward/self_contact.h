#pragma once
#include <array>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mvtwin/forward/symmetric_block_matrix.h"
#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

/// Options of leaflet self-contact (SelfContact) in a closure simulation, with its defaults
/// (Mansi et al. 2012, Sec. 2.3: alarm distance 0.6 mm, contact distance 0.3 mm, friction 0.5).
struct SelfContactOptions {
  bool enabled = true;  ///< off for sensitivity studies and the phantom's open frames
  double alarm_mm = 0.6;
  double contact_mm = 0.3;  ///< the contact (minimum) distance
  double friction = 0.5;
  double friction_slip_mm_per_s = 1.0;  ///< Coulomb friction is regularized below this slip
  /// Penalty stiffness per unit area = stiffness_factor x peak pressure / (alarm - contact), so
  /// that the peak pressure alone holds a vertex at alarm - (alarm - contact) / factor.
  double stiffness_factor = 2.0;
  /// Below the contact distance the stiffness grows to (1 + wall_factor) x its value at zero
  /// distance (see SelfContact), so that edge-on loads do not push free edges through.
  double wall_factor = 100.0;
  /// Continuous collision detection at the end of every step (SelfContact::find_crossing): a
  /// step that carries a vertex through a leaflet surface is retried with half the step.
  bool ccd = true;
  /// A step may leave a vertex up to this deep inside a leaflet's surface (mm) before continuous
  /// collision detection calls it a crossing; the contact law pushes a shallow one back out.
  /// 0 (the default): every pass through a surface is a crossing. A vertex pressed so hard that
  /// the law holds it at the surface itself (d = 0) then crosses and uncrosses it by round-off
  /// and every step is refused: the observation's last retry allows 0.1 mm
  /// (forward::observation_attempts; docs/virtual-patients.md). At most the contact distance.
  double ccd_depth_mm = 0.0;
  /// The static solve's contact distance over a smoothed surface (SelfContact, "The smooth
  /// distance"): the radius (mm) of the kernel that blends the other leaflet's face planes
  /// around a vertex's nearest point. 0: the nearest triangle's distance, as in the dynamic
  /// closure. 1.5 mm: Newton converged on 5 of bench closure's patients 1-5 (4 of 5 with 0),
  /// 9 of the unseen 41-50 (7 with 0); 1.0 and 2.0 mm on 4 and 3 of 1-5
  /// (docs/forward-status.md, "The smooth contact distance").
  double smooth_mm = 1.5;
  double exclusion_mm = 4.0;  ///< surface neighbours closer than this (unrolled) never pair
  double margin_mm = 1.5;     ///< Verlet margin of the candidate list

  bool is_valid(std::string* error) const;
  /// The penalty stiffness per unit area (N/mm^3) for a closure at peak pressure p (MPa; at
  /// least 10 mmHg is assumed, so that an unloaded valve still has contact).
  double stiffness_per_area(double peak_pressure_mpa) const;
  /// The pressure the penalty scales with for a peak pressure p (MPa): p, at least 10 mmHg
  /// (a diastole's negative peak, atrium above ventricle, gets the floor too).
  static double scaling_pressure_mpa(double peak_pressure_mpa);
};

/// Leaflet self-contact by vertex-triangle penalties (Mansi et al. 2012, Sec. 2.3: alarm distance
/// 0.6 mm, contact (minimum) distance 0.3 mm, friction 0.5).
///
/// Contact vertices are the corner nodes of the atrial and ventricular surfaces; contact
/// triangles are the triangles of both surfaces. A pair is ignored when the vertex and the
/// triangle are neighbours in the unrolled leaflet (closer than `exclusion_mm` in the plane):
/// those are kept apart by the elements themselves.
///
/// The normal force of a pair at distance d (N), with k = stiffness_per_area x the area the pair
/// stands for, d_a the alarm and d_c the contact distance:
///   F(d) = k (d_a - d)                                   d_c <= d < d_a
///   F(d) = k (d_a - d) + k_w (d_c - d)^2 / (2 d_c)       d < d_c,   k_w = wall_factor x k
/// so that the stiffness grows from k at d_c to k (1 + wall_factor) at d = 0 and beyond: a
/// free edge pressed edge-on against the other leaflet (its membrane load on a vertex of little
/// area) is held near the minimum distance instead of sinking in, while the law stays C1 (no
/// jump for the one linearization per step). Friction is lagged Coulomb friction regularized
/// below `friction_slip_mm_per_s`.
///
/// The distance d of a vertex is to the nearest triangle of each group (nearest by the unsigned
/// distance), signed so that it is negative inside the leaflet: over the triangle's face by the
/// face's outward side; where the nearest point is on an edge or a corner, by that feature's
/// pseudo-normal (the two faces' outward normals summed, or the faces around the corner
/// weighted by their angles there: Baerentzen and Aanaes 2005), so that d is continuous where
/// the nearest point passes from a face over an edge to the next face, inside as outside. On
/// the surface's boundary (the free edge, the commissures) d beyond an edge is positive.
///
/// The smooth distance (SelfContactOptions::smooth_mm = h > 0, while set_smooth(true): the
/// static solve). The nearest triangle's distance has a kink wherever the nearest face changes
/// (over a valley or a ridge of the other surface the force turns by the angle between the
/// faces), so that an equilibrium in a crease has no exact zero and Newton cannot converge to it
/// (virtual patient 3's commissural fold). Instead, a vertex p paired with a triangle measures
/// its distance to an implicit surface of the faces around that triangle (moving least squares
/// of the face planes, as in Shen, O'Brien and Shewchuk 2004): over the triangles t of the same
/// group, reached over the surface's edges and not the vertex's own neighbours, with centres c_t
/// within h of p, weights w_t = A_t (1 - |p - c_t|^2 / h^2)^3 (A_t the area), outward normals n_t,
///   f(p) = sum_t w_t n_t . (p - c_t) / sum_t w_t,
/// exact over a flat face and twice differentiable in every node. Beyond the surface's boundary
/// (the free edge, the annulus) the same mean over the boundary's edges e of the distance g_e
/// beyond each (in its face's plane, away from the face) gives g, and where g > 0 the vertex is
/// outside: d = sqrt(f^2 + g^2). The pair's energy is the law's, k(A) phi(d), with k from the
/// larger (smoothly) of the vertex's area and the kernel's mean triangle area; its force is
/// minus the energy's exact gradient (automatic differentiation per triangle and edge), its
/// stiffness the exact Hessian (central differences of those gradients, per triangle). Pairs
/// whose nearest triangle is up to 0.3 mm beyond the alarm distance are kept, so that the
/// smooth distance decides. Without friction (the static solve's rest state has none).
///
/// Tangent: the Gauss-Newton stiffness k(d) J^T n n^T J of each pair (J = [I, -w0, -w1, -w2]
/// maps the four nodes' motion to the vertex's motion relative to its closest point) plus the
/// friction damping. multiply() applies it with all vertex-triangle couplings (for an iterative
/// solve); add_diagonal_blocks() adds only its node-diagonal blocks to a fixed-pattern matrix
/// (a preconditioner: the couplings would change the sparsity pattern whenever the pairs
/// change).
///
/// The proximity search uses a hash grid of cell size d_a + margin and keeps the vertex-triangle
/// pairs within d_a + margin (a Verlet list). Until some node has moved by more than margin / 2
/// no search is done, only the distances of those candidates are updated; while the leaflets are
/// apart the list is empty and a step costs one displacement check.
class SelfContact {
 public:
  struct Pair {
    int vertex;               ///< node index
    std::array<int, 3> tri;   ///< node indices
    Eigen::Vector3d weights;  ///< barycentric weights of the closest point
    Eigen::Vector3d normal;   ///< direction that separates them (on the vertex's side)
    /// Signed: negative once the vertex is through the triangle (over its face) or on the inner
    /// side of the edge's or corner's pseudo-normal; -0.0 on such a feature itself.
    double distance;
    int triangle = -1;                ///< index of the nearest triangle in the surface
    double vertex_area = 0.0;         ///< the vertex's own area, mm^2
    int surface_vertex = -1;          ///< index of the vertex in the surface's vertices
    signed char outward = 1;          ///< the triangle's Surface::triangle_outward
    bool area_from_triangle = false;  ///< `area` is the triangle's (not the vertex's)
    double area;                      ///< surface area the vertex stands for, mm^2
    // Set by add_forces(): normal force (N) and stiffness (N/mm), friction coefficient
    // (N s/mm) and the tangential slip direction's projector is I - n n^T.
    double force = 0, stiffness = 0, eta = 0;
  };

  /// What can touch: contact vertices (node ids) and triangles (node ids), each with the index
  /// of its point in an unrolled `plane` (periodic in x with `period`, 0 = not periodic) used to
  /// exclude neighbours, and the surface area each vertex stands for.
  struct Surface {
    std::vector<int> vertices;
    std::vector<int> vertex_plane;
    std::vector<double> vertex_area;
    std::vector<std::array<int, 3>> triangles;
    std::vector<std::array<int, 3>> triangle_plane;
    /// Group of each triangle (the leaflet): a vertex pairs with the closest triangle of each
    /// group, so that a fold of its own leaflet cannot hide the other leaflet. Empty: one group.
    std::vector<int> triangle_group;
    /// +1 when the triangle's normal (b - a) x (c - a) points out of the solid it bounds, -1
    /// when it points in. Distances over a face are signed by it (negative inside the solid).
    std::vector<signed char> triangle_outward;
    Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> plane;
    double period = 0.0;
  };
  /// The atrial and ventricular surfaces of a valve model.
  static Surface valve_surface(const ValveModel& model);

  /// stiffness_per_area: N/mm^3 (SelfContactOptions::stiffness_per_area for a closure);
  /// max_depth_mm: a vertex over a face on its inner side deeper than this is left to the
  /// leaflet's other face (about half the leaflet thickness). Throws mvtwin::Error for invalid
  /// options or surface arrays of different sizes.
  SelfContact(Surface surface, const SelfContactOptions& options, double stiffness_per_area,
              double max_depth_mm);

  /// Updates the active pairs at positions x (all nodes, flattened). Returns the number of
  /// pairs within the alarm distance.
  int detect(const Eigen::VectorXd& x);
  /// Adds the forces of the pairs found by detect() (velocities v, all nodes, for friction) to
  /// f and keeps each pair's linearization. Returns the penalty energy (N mm).
  double add_forces(const Eigen::VectorXd& v, Eigen::VectorXd* f);
  /// y += (scale_k K + scale_c D) p over all nodes' dofs, with every coupling (K: Gauss-Newton
  /// contact stiffness, D: friction damping, at the last add_forces()).
  void multiply(const Eigen::VectorXd& p, double scale_k, double scale_c, Eigen::VectorXd* y) const;
  /// The exact stiffness of each pair found by the last add_forces() at positions x (the static
  /// solve's): minus the derivative of its normal force F(d) grad d, i.e. the Gauss-Newton
  /// term plus -F(d) times the distance's Hessian (the normal's rotation; a central difference
  /// of the exact grad d, 1e-6 mm) plus, where the triangle's area sets the pair stiffness k,
  /// the force's change with that area. Not symmetric. Without friction. For multiply_exact().
  void linearize_exact(const Eigen::VectorXd& x);
  /// y += K p over all nodes' dofs with the exact pair stiffnesses of linearize_exact().
  void multiply_exact(const Eigen::VectorXd& p, Eigen::VectorXd* y) const;
  /// Adds the node-diagonal 3x3 blocks of scale_k K + scale_c D to A.
  void add_diagonal_blocks(double scale_k, double scale_c, SymmetricBlockMatrix* A) const;
  /// add_forces() and, as triplets over node dofs, scale_k K + scale_c D with every coupling
  /// (the whole matrix, for tests; the simulation uses multiply and add_diagonal_blocks).
  double add(const Eigen::VectorXd& v, Eigen::VectorXd* f,
             std::vector<Eigen::Triplet<double>>* triplets, double scale_k, double scale_c);
  /// Normal force (N) and stiffness (N/mm) of the law above at distance d for pair stiffness k.
  void law(double d, double k, double* force, double* stiffness) const;

  /// Continuous collision detection over a step: every node moving linearly from x0 to x1, the
  /// first contact vertex that passes through a contact triangle (not one of its neighbours),
  /// or -1. Only candidate pairs can cross when no node has moved by more than margin / 2 from
  /// the last search at either end (their distance changes by at most the sum of the motions);
  /// otherwise the step's swept boxes are searched first. A step that carries a vertex through
  /// the other leaflet (tunnelling, at large steps) is to be retried with a smaller step.
  int find_crossing(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const;

  /// Threads of the searches, detect() and find_crossing() (1 or 2): each splits its loop in two
  /// halves whose results are joined in order, so results do not depend on it.
  void set_threads(int threads) { threads_ = threads; }
  /// Changes the friction coefficient (the settling phase turns friction off).
  void set_friction(double friction) { opt_.friction = friction; }
  /// The smooth distance (SelfContactOptions::smooth_mm) on or off: the static solve turns it
  /// on while it runs (no effect when smooth_mm is 0).
  void set_smooth(bool on) {
    smooth_ = on && opt_.smooth_mm > 0.0;
    if (!smooth_) smooth_sets_.clear();
  }

  const std::vector<Pair>& pairs() const { return pairs_; }
  /// Full searches done, and detections that reused the candidate list instead.
  int searches() const { return searches_; }
  int reused() const { return reused_; }
  /// Smallest distance among the candidates at the last detection (infinity if none).
  double min_distance() const { return min_distance_; }

 private:
  void full_search(const Eigen::VectorXd& x);
  // The closest pairs of candidates [k0, k1) (whole vertices) at x, appended to *pairs.
  void closest_pairs(const Eigen::VectorXd& x, size_t k0, size_t k1, std::vector<Pair>* pairs,
                     double* min_distance) const;
  /// Whether surface vertex i is within the exclusion distance (in the unrolled plane) of a
  /// corner of triangle t: such pairs are neighbours on the leaflet, not contacts.
  bool excluded(int i, int t) const;
  /// -1 when p, whose closest point on triangle t (barycentric w) lies on an edge or a corner,
  /// is on the inner side of that feature's pseudo-normal at x; +1 otherwise, and on the
  /// surface's boundary (an edge of one triangle, a corner on such an edge), beyond which lies
  /// the outside.
  signed char feature_side(const Eigen::VectorXd& x, int t, const Eigen::Vector3d& w,
                           const Eigen::Vector3d& p_minus_q) const;

  SelfContactOptions opt_;
  double stiffness_per_area_ = 0.0, max_depth_mm_ = 0.0;
  Surface s_;
  std::vector<Pair> pairs_;
  std::vector<Eigen::Matrix<double, 12, 12>> exact_;  // per pair, from linearize_exact()
  // The smooth distance: per pair (empty where the pair keeps the nearest triangle's distance,
  // beyond the surface's boundary), the nodes of its kernel's triangles (the vertex first), the
  // triangles over those local indices and their outward signs; its exact stiffness from
  // linearize_exact().
  struct SmoothSet {
    std::vector<int> nodes;
    std::vector<std::array<int, 3>> tris;
    std::vector<signed char> outward;
    // The surface's boundary edges near the vertex: corners 0 and 1, and the third corner of
    // their triangle (local indices), whose side is inside.
    std::vector<std::array<int, 3>> edges;
    double vertex_area = 0.0;
    Eigen::MatrixXd K;
  };
  std::vector<SmoothSet> smooth_sets_;
  bool smooth_ = false;
  Eigen::VectorXd x_detect_;  // positions at the last detect() (the smooth distance's)
  // The smooth set of pair pr at x (false: the pair keeps the nearest triangle's distance).
  bool gather_smooth(const Pair& pr, const Eigen::VectorXd& x, SmoothSet* set) const;
  // The pair's energy (N mm) over its smooth set at the set's node positions X (3 per node),
  // with its gradient and Hessian when asked, and the smooth distance.
  double smooth_energy(const SmoothSet& set, const Eigen::VectorXd& X, Eigen::VectorXd* gradient,
                       Eigen::MatrixXd* hessian, double* distance) const;
  // Per triangle, in the unrolled plane: the centre of its corners, and the squared
  // centre-to-vertex distances below which every corner (inside2) and above which no corner
  // (outside2) is within the exclusion distance of the vertex; between them excluded() looks
  // at the corners.
  std::vector<Eigen::Vector2d> triangle_centre_;
  std::vector<double> triangle_inside2_, triangle_outside2_;
  std::vector<Eigen::Vector2d> vertex_uv_;  // each surface vertex in the unrolled plane
  // The surface's connectivity: per triangle and edge k (corners k, k + 1), the triangle across
  // it (-1 on the boundary); per node, the triangles around it, and whether it lies on the
  // boundary (feature_side()).
  std::vector<std::array<int, 3>> edge_neighbour_;
  std::unordered_map<int, std::vector<int>> node_triangles_;
  std::unordered_set<int> node_on_boundary_;
  // The full search takes the triangles in consecutive groups (valve_surface's quadratic faces
  // are four consecutive triangles). Per group, in the unrolled plane: a centre and the squared
  // distance from it below which a vertex is excluded from every triangle of the group.
  static constexpr size_t kSearchGroup = 4;
  std::vector<Eigen::Vector2d> group_centre_;
  std::vector<double> group_inside2_;
  struct Candidate {
    int vertex;  // index into the surface's vertices
    int triangle;
  };
  std::vector<Candidate> candidates_;  // by vertex
  Eigen::VectorXd x_search_;           // positions at the last full search
  int searches_ = 0, reused_ = 0, threads_ = 1;
  double min_distance_ = 0.0;
};

}  // namespace mvtwin::forward
