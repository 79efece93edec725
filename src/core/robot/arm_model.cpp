// An arm's URDF read into a KDL tree (links' inertials, joints' axes) and its transmissions read from the XML.
#include "backlash_servo/robot/arm_model.h"

#include <tinyxml2.h>
#include <urdf_parser/urdf_parser.h>
#include <kdl/tree.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace backlash_servo
{
namespace
{
const char* const SIMPLE_TRANSMISSION = "transmission_interface/SimpleTransmission";

KDL::Vector toKdl(const urdf::Vector3& v)
{
  return KDL::Vector(v.x, v.y, v.z);
}

KDL::Frame toKdl(const urdf::Pose& p)
{
  return KDL::Frame(KDL::Rotation::Quaternion(p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w),
                    toKdl(p.position));
}

bool isMovable(const urdf::Joint& joint)
{
  return joint.type == urdf::Joint::REVOLUTE || joint.type == urdf::Joint::CONTINUOUS ||
         joint.type == urdf::Joint::PRISMATIC;
}

KDL::Joint jointOf(const urdf::Joint& joint)
{
  const KDL::Frame origin = toKdl(joint.parent_to_joint_origin_transform);
  if (!isMovable(joint))
  {
    return KDL::Joint(joint.name, KDL::Joint::None);  // fixed; floating and planar joints are held too
  }
  const KDL::Vector axis = toKdl(joint.axis);
  if (!(axis.Norm() > 0.0))
  {
    throw std::invalid_argument("URDF joint '" + joint.name + "': <axis> must be a non-zero vector");
  }
  return KDL::Joint(joint.name, origin.p, origin.M * (axis / axis.Norm()),
                    joint.type == urdf::Joint::PRISMATIC ? KDL::Joint::TransAxis : KDL::Joint::RotAxis);
}

/// The link's inertial in KDL's convention: mass, centre of mass and rotational inertia about it, all in the link's
/// frame (URDF gives the inertia in the inertial's own frame: rotated into the link's).
KDL::RigidBodyInertia inertiaOf(const urdf::Link& link)
{
  if (!link.inertial)
  {
    return KDL::RigidBodyInertia(0.0);
  }
  const urdf::Inertial& i = *link.inertial;
  const double values[] = {i.mass, i.ixx, i.iyy, i.izz, i.ixy, i.ixz, i.iyz};
  for (double v : values)
  {
    if (!std::isfinite(v))
    {
      throw std::invalid_argument("URDF link '" + link.name + "': <inertial> values must be finite");
    }
  }
  if (i.mass < 0.0 || i.ixx < 0.0 || i.iyy < 0.0 || i.izz < 0.0)
  {
    throw std::invalid_argument("URDF link '" + link.name + "': <mass> and <inertia> ixx, iyy, izz must be ≥ 0 (mass " +
                                std::to_string(i.mass) + " kg)");
  }
  const KDL::Frame origin = toKdl(i.origin);
  const KDL::RigidBodyInertia about_com_rotated =
      origin.M *
      KDL::RigidBodyInertia(0.0, KDL::Vector::Zero(), KDL::RotationalInertia(i.ixx, i.iyy, i.izz, i.ixy, i.ixz, i.iyz));
  return KDL::RigidBodyInertia(i.mass, origin.p, about_com_rotated.getRotationalInertia());
}

/// Whether the link or a link below it has mass or rotational inertia (else it moves nothing of the arm's dynamics).
bool carriesMass(const urdf::Link& link)
{
  const auto& i = link.inertial;
  if (i && (i->mass != 0.0 || i->ixx != 0.0 || i->iyy != 0.0 || i->izz != 0.0))
  {
    return true;
  }
  return std::any_of(link.child_links.begin(), link.child_links.end(),
                     [](const urdf::LinkSharedPtr& child) { return carriesMass(*child); });
}

/// The movable joints of the subtree from `link` (its own joint first), depth-first.
void movableJoints(const urdf::Link& link, std::vector<urdf::JointConstSharedPtr>* out)
{
  if (isMovable(*link.parent_joint))
  {
    out->push_back(link.parent_joint);
  }
  for (const urdf::LinkSharedPtr& child : link.child_links)
  {
    movableJoints(*child, out);
  }
}

/// Adds the link and those below it to the tree, except subtrees without mass (a motor's drawing, a mark): they
/// change neither gravity nor inertia, and their movable joints go to `massless` instead.
void addSubtree(const urdf::Link& link, KDL::Tree* tree, std::vector<urdf::JointConstSharedPtr>* massless)
{
  if (!carriesMass(link))
  {
    movableJoints(link, massless);
    return;
  }
  const urdf::Joint& joint = *link.parent_joint;
  const KDL::Segment segment(link.name, jointOf(joint), toKdl(joint.parent_to_joint_origin_transform), inertiaOf(link));
  if (!tree->addSegment(segment, joint.parent_link_name))
  {
    throw std::invalid_argument("URDF link '" + link.name + "': cannot attach it to '" + joint.parent_link_name + "'");
  }
  for (const urdf::LinkSharedPtr& child : link.child_links)
  {
    addSubtree(*child, tree, massless);
  }
}

const char* textOf(const tinyxml2::XMLElement* e)
{
  return e != nullptr && e->GetText() != nullptr ? e->GetText() : "";
}

/// <transmission> elements: type SimpleTransmission, one <joint name> and one <actuator name>, the reduction from
/// the actuator's (or the joint's) <mechanicalReduction>. Returns joint name → (reduction, actuator).
std::map<std::string, std::pair<double, std::string>> transmissionsOf(const tinyxml2::XMLElement* robot)
{
  std::map<std::string, std::pair<double, std::string>> found;
  for (const tinyxml2::XMLElement* t = robot->FirstChildElement("transmission"); t != nullptr;
       t = t->NextSiblingElement("transmission"))
  {
    const std::string name = t->Attribute("name") != nullptr ? t->Attribute("name") : "";
    const std::string where = "URDF transmission '" + name + "'";
    const tinyxml2::XMLElement* type = t->FirstChildElement("type");
    const std::string type_text = type != nullptr ? textOf(type) : (t->Attribute("type") ? t->Attribute("type") : "");
    if (type_text != SIMPLE_TRANSMISSION)
    {
      throw std::invalid_argument(where + ": type '" + type_text + "' is not " + SIMPLE_TRANSMISSION +
                                  " (the only one a geared joint here has)");
    }
    const tinyxml2::XMLElement* joint = t->FirstChildElement("joint");
    const tinyxml2::XMLElement* actuator = t->FirstChildElement("actuator");
    if (joint == nullptr || joint->Attribute("name") == nullptr || actuator == nullptr ||
        actuator->Attribute("name") == nullptr)
    {
      throw std::invalid_argument(where + ": needs <joint name=…> and <actuator name=…>");
    }
    const tinyxml2::XMLElement* reduction = actuator->FirstChildElement("mechanicalReduction");
    if (reduction == nullptr)
    {
      reduction = joint->FirstChildElement("mechanicalReduction");
    }
    double n = 1.0;  // SimpleTransmission's default when none is given
    if (reduction != nullptr &&
        (reduction->QueryDoubleText(&n) != tinyxml2::XML_SUCCESS || !std::isfinite(n) || n == 0.0))
    {
      throw std::invalid_argument(where + ": <mechanicalReduction> must be a finite non-zero number (got '" +
                                  std::string(textOf(reduction)) + "')");
    }
    if (!found.emplace(joint->Attribute("name"), std::make_pair(n, std::string(actuator->Attribute("name")))).second)
    {
      throw std::invalid_argument(where + ": joint '" + joint->Attribute("name") + "' has a transmission already");
    }
  }
  return found;
}
/// A movable URDF joint as the arm lists it: name, limits and its transmission (if the URDF gives one).
ArmJoint armJointOf(const urdf::Joint& uj, const std::map<std::string, std::pair<double, std::string>>& transmissions)
{
  ArmJoint j;
  j.name = uj.name;
  j.prismatic = uj.type == urdf::Joint::PRISMATIC;
  if (uj.type != urdf::Joint::CONTINUOUS && uj.limits)
  {
    j.lower = uj.limits->lower;
    j.upper = uj.limits->upper;
  }
  if (uj.limits)
  {
    j.velocity_limit = uj.limits->velocity;
    j.effort_limit = uj.limits->effort;
  }
  const auto t = transmissions.find(j.name);
  if (t != transmissions.end())
  {
    j.reduction = t->second.first;
    j.actuator = t->second.second;
  }
  return j;
}
}  // namespace

/// The arm's bodies flattened, parents before children, and the recursive Newton–Euler inverse dynamics over them
/// at rest (q̇ = 0: what gravity and the mass matrix need). Hand-written over arrays: KDL's tree solver looks every
/// segment up by name in a map and allocates per pass, several times the arithmetic.
struct ArmModel::Dynamics
{
  struct Body
  {
    KDL::Segment segment;  // joint, the frame from the parent's tip to this body's, the inertia
    int parent = -1;       // index in bodies; -1: attached to the root link
    int q = -1;            // index of its joint in the pose (KDL's q_nr); -1: fixed
  };
  KDL::Tree tree;
  std::vector<Body> bodies;
  std::vector<int> kdl_index;  // joints_[i] → its q_nr in the tree; -1: a massless subtree's
  // Scratch of one pass (one thread at a time): each body's frame from its parent, joint twist, acceleration, wrench.
  mutable std::vector<KDL::Frame> x;
  mutable std::vector<KDL::Twist> s, a;
  mutable std::vector<KDL::Wrench> f;
  mutable std::vector<double> q_kdl;

  void flatten(const KDL::TreeElement& element, int parent)
  {
    for (const KDL::SegmentMap::const_iterator& child : GetTreeElementChildren(element))
    {
      const KDL::TreeElement& e = child->second;
      Body b;
      b.segment = GetTreeElementSegment(e);
      b.parent = parent;
      b.q = b.segment.getJoint().getType() == KDL::Joint::None ? -1 : static_cast<int>(GetTreeElementQNr(e));
      bodies.push_back(b);
      flatten(e, static_cast<int>(bodies.size()) - 1);
    }
  }

  /// The pose in KDL's numbering from q in the arm's.
  void setPose(const Eigen::VectorXd& q) const
  {
    q_kdl.assign(tree.getNrOfJoints(), 0.0);
    for (std::size_t i = 0; i < kdl_index.size(); ++i)
    {
      if (kdl_index[i] >= 0)
      {
        q_kdl[static_cast<std::size_t>(kdl_index[i])] = q(static_cast<Eigen::Index>(i));
      }
    }
  }

  /**
   * τ = M(q) q̈ − τ_g(q) at rest: the joint torques [N·m] that give the bodies the joint accelerations `qdd` (only
   * joint `accelerated` has one, of 1; −1: none) with the root accelerating upwards by `g` [m/s²] (gravity's
   * equivalent), into tau (KDL's numbering). Pose from setPose().
   */
  void inverseDynamics(int accelerated, double g, std::vector<double>* tau) const
  {
    const std::size_t n = bodies.size();
    x.resize(n);
    s.resize(n);
    a.resize(n);
    f.resize(n);
    tau->assign(tree.getNrOfJoints(), 0.0);
    const KDL::Twist root(KDL::Vector(0.0, 0.0, g), KDL::Vector::Zero());  // −(gravity) as the root's acceleration
    for (std::size_t i = 0; i < n; ++i)
    {
      const Body& b = bodies[i];
      const double qi = b.q >= 0 ? q_kdl[static_cast<std::size_t>(b.q)] : 0.0;
      x[i] = b.segment.pose(qi);
      s[i] = x[i].M.Inverse(b.segment.twist(qi, 1.0));  // the joint's unit twist in the body's frame
      a[i] = x[i].Inverse(b.parent >= 0 ? a[static_cast<std::size_t>(b.parent)] : root);
      if (b.q >= 0 && b.q == accelerated)
      {
        a[i] += s[i];
      }
      f[i] = b.segment.getInertia() * a[i];  // at rest: no velocity terms
    }
    for (std::size_t i = n; i-- > 0;)
    {
      const Body& b = bodies[i];
      if (b.q >= 0)
      {
        (*tau)[static_cast<std::size_t>(b.q)] = KDL::dot(s[i], f[i]);
      }
      if (b.parent >= 0)
      {
        f[static_cast<std::size_t>(b.parent)] += x[i] * f[i];
      }
    }
  }
};

ArmModel::ArmModel(const std::string& urdf_xml) : dynamics_(std::make_unique<Dynamics>())
{
  tinyxml2::XMLDocument doc;
  if (doc.Parse(urdf_xml.c_str(), urdf_xml.size()) != tinyxml2::XML_SUCCESS)
  {
    throw std::invalid_argument(std::string("URDF: not well-formed XML (") + doc.ErrorStr() + ")");
  }
  const tinyxml2::XMLElement* robot = doc.FirstChildElement("robot");
  if (robot == nullptr)
  {
    throw std::invalid_argument("URDF: no <robot> element");
  }
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
  if (!model || !model->getRoot())
  {
    throw std::invalid_argument(
        "URDF: not a valid robot description (urdfdom refused it, its reason printed above: every joint needs its "
        "parent and child links, "
        "one root link, well-formed origins, axes and limits)");
  }
  robot_name_ = model->getName();
  dynamics_->tree = KDL::Tree(model->getRoot()->name);
  std::vector<urdf::JointConstSharedPtr> massless;
  for (const urdf::LinkSharedPtr& child : model->getRoot()->child_links)
  {
    addSubtree(*child, &dynamics_->tree, &massless);
  }
  const auto transmissions = transmissionsOf(robot);
  // KDL numbers the movable joints depth-first; keep that order.
  std::vector<std::pair<int, ArmJoint>> ordered;
  for (const auto& [name, element] : dynamics_->tree.getSegments())
  {
    const KDL::Joint& kj = element.segment.getJoint();
    if (kj.getType() == KDL::Joint::None)
    {
      continue;
    }
    ordered.emplace_back(static_cast<int>(element.q_nr), armJointOf(*model->getJoint(kj.getName()), transmissions));
  }
  for (const auto& [joint, unused] : transmissions)
  {
    const urdf::JointConstSharedPtr uj = model->getJoint(joint);
    if (!uj || !isMovable(*uj))
    {
      throw std::invalid_argument("URDF transmission of joint '" + joint +
                                  "': the URDF has no movable joint by that name");
    }
  }
  std::sort(ordered.begin(), ordered.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [index, joint] : ordered)
  {
    dynamics_->kdl_index.push_back(index);
    joints_.push_back(joint);
  }
  for (const urdf::JointConstSharedPtr& uj : massless)
  {
    dynamics_->kdl_index.push_back(-1);
    joints_.push_back(armJointOf(*uj, transmissions));
  }
  dynamics_->flatten(dynamics_->tree.getRootSegment()->second, -1);
}

ArmModel::~ArmModel() = default;

int ArmModel::indexOf(const std::string& name) const
{
  for (std::size_t i = 0; i < joints_.size(); ++i)
  {
    if (joints_[i].name == name)
    {
      return static_cast<int>(i);
    }
  }
  return -1;
}

Eigen::VectorXd ArmModel::gravityOnLoad(const Eigen::VectorXd& q, double g) const
{
  dynamics_->setPose(q);
  std::vector<double> held;
  dynamics_->inverseDynamics(-1, g, &held);
  Eigen::VectorXd on_load(static_cast<Eigen::Index>(joints_.size()));
  for (std::size_t i = 0; i < joints_.size(); ++i)
  {
    const int k = dynamics_->kdl_index[i];
    on_load(static_cast<Eigen::Index>(i)) = k >= 0 ? -held[static_cast<std::size_t>(k)] : 0.0;  // opposes holding
  }
  return on_load;
}

Eigen::MatrixXd ArmModel::massMatrix(const Eigen::VectorXd& q) const
{
  const auto count = static_cast<Eigen::Index>(joints_.size());
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(count, count);
  for (Eigen::Index c = 0; c < count; ++c)
  {
    m.col(c) = massColumn(q, static_cast<std::size_t>(c));
  }
  return m;
}

double ArmModel::inertiaAbout(const Eigen::VectorXd& q, std::size_t i) const
{
  return massColumn(q, i)(static_cast<Eigen::Index>(i));
}

Eigen::VectorXd ArmModel::massColumn(const Eigen::VectorXd& q, std::size_t c) const
{
  const auto count = static_cast<Eigen::Index>(joints_.size());
  Eigen::VectorXd out = Eigen::VectorXd::Zero(count);
  const int kc = dynamics_->kdl_index.at(c);
  if (kc < 0)
  {
    return out;  // a massless subtree's joint moves no mass
  }
  // The torques that give joint c a unit acceleration from rest without gravity: M(q) e_c.
  dynamics_->setPose(q);
  std::vector<double> column;
  dynamics_->inverseDynamics(kc, 0.0, &column);
  for (Eigen::Index r = 0; r < count; ++r)
  {
    const int kr = dynamics_->kdl_index[static_cast<std::size_t>(r)];
    out(r) = kr >= 0 ? column[static_cast<std::size_t>(kr)] : 0.0;
  }
  return out;
}

}  // namespace backlash_servo
